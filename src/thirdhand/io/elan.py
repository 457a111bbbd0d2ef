"""ELAN annotation files (``.eaf``, and ELAN's tab-delimited text export) as Labels.

The 3rdHand annotators kept one ELAN tier per labelled body pair, named like the
entries of ``ann_kvg.kvg``: ``TS <hand> <object>`` (one annotation per hand-object
interaction phase) and ``CE <parent> <child>`` (one annotation per constraint,
from its onset to the end of the recording). Annotation values are empty.
Tiers named otherwise are ignored (annotators' notes).

ELAN times are milliseconds on the **video** clock (``TIME_UNITS="milliseconds"``,
``MEDIA_DESCRIPTOR`` names the camera file), not on the motion-capture clock. On
toolbox_3, ELAN and ``ann_kvg.kvg`` hold the same 20 tiers with the same number of
phases in the same order, and every frame boundary corresponds to one media time
(but one phase end, typed 10 ms off), monotonically; yet no affine clock maps one
onto the other: the best fit (40.26 frames per media second, frame 0 about 49 s
before the video starts) leaves residuals up to 1.6 s (RMS 0.5 s), and the
constraints' ends (the end of each recording) differ by 22 s. Attaching ELAN
labels to a recording therefore takes an ``offset`` that the caller vouches for.
``ann.txt`` is ELAN's tab-delimited export of the same tiers, in seconds, and
agrees with ``elan.eaf`` to the millisecond.

ELAN files are read with ``pympi`` (package ``pympi-ling``).
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path
from xml.etree.ElementTree import ParseError

from thirdhand.demonstration import BodyInfo, Labels
from thirdhand.errors import FormatError
from thirdhand.io.kvg import Annotation, annotations_to_labels, last_span_end
from thirdhand.readlimits import check_xml_depth, read_input, read_text_input

_TIER = re.compile(r"^(TS|CE)\s+(\S+)\s+(\S+)\s*$")


def _tier_annotation(
    tier: str, spans: list[tuple[float, float]], *, path: Path, line: int | None
) -> Annotation | None:
    tag = tier.split(maxsplit=1)[0] if tier.strip() else ""
    if tag not in ("TS", "CE"):
        return None
    m = _TIER.match(tier.strip())
    if m is None:
        raise FormatError(
            path, f"tier {tier!r}: expected '{tag} <body a> <body b>'", line=line, where="tier"
        )
    for s, e in spans:
        if not s <= e:
            raise FormatError(
                path, f"tier {tier!r}: annotation starts at {s} s after its end {e} s", line=line
            )
    spans.sort()
    return Annotation(m[1], m[2], m[3], tuple(spans), tuple({} for _ in spans), line)


def parse_eaf(path: str | os.PathLike[str]) -> list[Annotation]:
    """The ``TS``/``CE`` tiers of an ELAN file, spans in seconds of media time.

    Each entry's ``line`` is the line of its ``<TIER>`` element.

    Raises
    ------
    FormatError
        Not a readable ELAN file, or a ``TS``/``CE`` tier whose name does not hold two
        bodies, or an annotation whose end precedes its start.
    """
    import pympi

    p = Path(path)
    raw = read_input(p, what="ELAN file")
    check_xml_depth(raw, error=lambda m: FormatError(p, f"not a readable ELAN file: {m}"))
    try:
        text = raw.decode("utf-8")
        eaf = pympi.Elan.Eaf(str(p))
    except (OSError, UnicodeDecodeError, ParseError) as exc:
        raise FormatError(p, f"not a readable ELAN file: {exc}") from None
    except Exception as exc:  # pympi raises a bare Exception for XML it cannot parse
        raise FormatError(p, f"not a readable ELAN file: {exc}") from None
    out: list[Annotation] = []
    for tier in eaf.get_tier_names():
        pos = text.find(f'TIER_ID="{tier}"')
        line = text.count("\n", 0, pos) + 1 if pos >= 0 else None
        try:
            data = eaf.get_annotation_data_for_tier(tier)
        except (KeyError, ValueError, TypeError) as exc:
            raise FormatError(p, f"tier {tier!r}: {exc}", line=line) from None
        spans: list[tuple[float, float]] = []
        for row in data:
            start, end = row[0], row[1]
            if start is None or end is None:
                raise FormatError(p, f"tier {tier!r}: annotation without a time", line=line)
            spans.append((start / 1000.0, end / 1000.0))
        ann = _tier_annotation(tier, spans, path=p, line=line)
        if ann is not None:
            out.append(ann)
    if not out:
        raise FormatError(p, "no 'TS <hand> <object>' or 'CE <a> <b>' tier")
    return out


def parse_tab(path: str | os.PathLike[str]) -> list[Annotation]:
    """The ``TS``/``CE`` tiers of ELAN's tab-delimited export (``ann.txt``), in seconds.

    Lines are ``tier <TAB> [participant] <TAB> start_s <TAB> end_s [<TAB> value]``;
    an entry's ``line`` is the line of the tier's first annotation.
    """
    p = Path(path)
    try:
        lines = read_text_input(p, what="ELAN tab export").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise FormatError(p, f"cannot read: {exc}") from None
    tiers: dict[str, tuple[int, list[tuple[float, float]]]] = {}
    for k, raw in enumerate(lines, start=1):
        if not raw.strip():
            continue
        cells = raw.split("\t")
        if len(cells) < 4:
            raise FormatError(
                p, f"expected tier, participant, start, end separated by tabs, got {raw!r}", line=k
            )
        try:
            start, end = float(cells[2]), float(cells[3])
        except ValueError:
            raise FormatError(
                p, f"start/end {cells[2]!r}, {cells[3]!r} are not seconds", line=k
            ) from None
        tiers.setdefault(cells[0].strip(), (k, []))[1].append((start, end))
    out = [
        a
        for tier, (line, spans) in tiers.items()
        if (a := _tier_annotation(tier, spans, path=p, line=line)) is not None
    ]
    if not out:
        raise FormatError(p, "no 'TS <hand> <object>' or 'CE <a> <b>' tier")
    return out


def _labels(
    entries: list[Annotation],
    path: Path,
    *,
    offset: float,
    end: float | None,
    bodies: Sequence[BodyInfo] | None,
) -> Labels:
    last = last_span_end(entries) if end is None else end
    return annotations_to_labels(
        entries, lambda s, line: s + offset, path=path, last=last, bodies=bodies
    )


def read_eaf(
    path: str | os.PathLike[str],
    *,
    offset: float = 0.0,
    end: float | None = None,
    bodies: Sequence[BodyInfo] | None = None,
) -> Labels:
    """Read an ELAN ``.eaf`` file into Labels.

    Parameters
    ----------
    path : path-like
    offset : float
        Seconds added to ELAN's media time to land on the recording's time axis.
    end : float, optional
        End of the recording, seconds of media time: a ``CE`` annotation ending before
        it yields a removal event. Defaults to the latest annotation end in the file.
    bodies : sequence of BodyInfo, optional
        The recording's bodies: names are checked and hand labels (``/human/rh``)
        expanded to the hand's tracked fingers (see :func:`thirdhand.io.kvg.resolve_body`).

    Returns
    -------
    Labels
        ``TS`` tiers as interaction intervals, ``CE`` tiers as ``fixed`` constraint onsets.
    """
    p = Path(path)
    return _labels(parse_eaf(p), p, offset=offset, end=end, bodies=bodies)


def read_tab(
    path: str | os.PathLike[str],
    *,
    offset: float = 0.0,
    end: float | None = None,
    bodies: Sequence[BodyInfo] | None = None,
) -> Labels:
    """Read ELAN's tab-delimited export (``ann.txt``) into Labels; as :func:`read_eaf`."""
    p = Path(path)
    return _labels(parse_tab(p), p, offset=offset, end=end, bodies=bodies)


__all__ = ["parse_eaf", "parse_tab", "read_eaf", "read_tab"]
