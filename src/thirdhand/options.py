"""Checks of command-line options: one clear :class:`~thirdhand.errors.OptionError` each.

Every command validates its options with these before doing any work, so a
nonsense value (``--rate inf``, ``--seed -1``, ``--port 99999``) is one line on
stderr and a non-zero exit, never a traceback, a hang or a silent default.
"""

from __future__ import annotations

import ipaddress
import math
import socket
import threading
from collections.abc import Sequence

from thirdhand.errors import OptionError

#: Largest seed numpy's ``default_rng`` and the planners accept (64 bits unsigned).
MAX_SEED = 2**63 - 1


def finite(
    option: str,
    value: float,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
) -> float:
    """``value`` as a float, checked finite and inside ``[low, high]`` (``(low, high]``).

    Raises
    ------
    OptionError
        ``--rate: expected a finite number > 0, got inf``.
    """
    v = float(value)
    want = "a finite number"
    if low is not None:
        want += f" {'>' if low_open else '>='} {low:g}"
    if high is not None:
        want += f"{' and' if low is not None else ''} <= {high:g}"
    bad = not math.isfinite(v)
    bad |= low is not None and (v <= low if low_open else v < low)
    bad |= high is not None and v > high
    if bad:
        raise OptionError(f"{option}: expected {want}, got {value:g}")
    return v


def integer(option: str, value: int, *, low: int | None = None, high: int | None = None) -> int:
    """``value`` checked inside ``[low, high]``.

    Raises
    ------
    OptionError
        ``--skills: expected an integer >= 1, got 0``.
    """
    parts = []
    if low is not None:
        parts.append(f">= {low}")
    if high is not None:
        parts.append(f"<= {high}")
    if (low is not None and value < low) or (high is not None and value > high):
        raise OptionError(f"{option}: expected an integer {' and '.join(parts)}, got {value}")
    return int(value)


def seed(value: int, option: str = "--seed") -> int:
    """A random seed: an integer from 0 to 2**63 - 1."""
    return integer(option, value, low=0, high=MAX_SEED)


def vector(option: str, values: Sequence[float], size: int, *, nonzero: bool = False) -> tuple:
    """A vector of ``size`` finite numbers (not all zero when ``nonzero``)."""
    vals = tuple(float(v) for v in values)
    if len(vals) != size:
        raise OptionError(f"{option}: expected {size} numbers, got {len(vals)}")
    if not all(math.isfinite(v) for v in vals):
        raise OptionError(f"{option}: expected finite numbers, got {','.join(map(str, vals))}")
    if nonzero and not any(vals):
        raise OptionError(f"{option}: expected a non-zero vector, got {','.join(map(str, vals))}")
    return vals


def port(value: int, option: str = "--port") -> int:
    """A TCP port: 0 (any free one) to 65535."""
    return integer(option, value, low=0, high=65535)


def host(value: str, option: str = "--host", *, timeout_s: float = 5.0) -> str:
    """An address to bind: an IP literal, or a name that resolves within ``timeout_s``.

    The name is resolved in a helper thread so an unreachable name server
    cannot hang the command.
    """
    if not value or any(c.isspace() for c in value):
        raise OptionError(f"{option}: expected an address or host name, got {value!r}")
    try:
        ipaddress.ip_address(value)
        return value
    except ValueError:
        pass
    result: list[BaseException | None] = []

    def resolve() -> None:
        try:
            socket.getaddrinfo(value, None)
            result.append(None)
        except (OSError, UnicodeError) as exc:
            result.append(exc)

    worker = threading.Thread(target=resolve, daemon=True)
    worker.start()
    worker.join(timeout_s)
    if not result:
        raise OptionError(f"{option}: {value!r} did not resolve within {timeout_s:g} s")
    if result[0] is not None:
        raise OptionError(f"{option}: cannot resolve {value!r} ({result[0]})")
    return value


#: Most body pairs the pairwise stages (segmentation, constraint detection) take on:
#: about 200 bodies. Their time and memory grow with the number of pairs.
MAX_BODY_PAIRS = 20000


def body_pairs(n_bodies: int, source: str) -> int:
    """The number of body pairs of a recording, refused beyond :data:`MAX_BODY_PAIRS`.

    Raises
    ------
    OptionError
        ``rec.csv: 10000 bodies make 49995000 body pairs; the pairwise stages take
        at most 20000 (about 200 bodies): select the bodies first``.
    """
    pairs = n_bodies * (n_bodies - 1) // 2
    if pairs > MAX_BODY_PAIRS:
        raise OptionError(
            f"{source}: {n_bodies} bodies make {pairs} body pairs; the pairwise stages take "
            f"at most {MAX_BODY_PAIRS} (about 200 bodies): select the bodies first "
            "(Demonstration.select)"
        )
    return pairs


__all__ = [
    "MAX_BODY_PAIRS",
    "MAX_SEED",
    "body_pairs",
    "finite",
    "host",
    "integer",
    "port",
    "seed",
    "vector",
]
