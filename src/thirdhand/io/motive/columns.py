"""Which columns of a Motive export hold which body's rotation and position."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from thirdhand.errors import FormatError
from thirdhand.io.motive.header import _Header


@dataclass
class _BodySpec:
    """Columns of one body: ``quat`` (x y z w) is None for a position-only marker."""

    name: str
    asset: str
    pos: list[int]
    quat: list[int] | None
    ident: str = ""


def _find_bodies(path: Path, header: _Header, include_markers: bool) -> list[_BodySpec]:
    """Group the columns of rigid bodies (and labelled markers) by asset."""
    rows = header.rows
    types, names, comps, axes = rows["type"], rows["name"], rows["component"], rows["axis"]
    ids = rows.get("id", [""] * header.n_cols)
    wanted = {"Rigid Body"} | ({"Marker"} if include_markers else set())
    found: dict[tuple[str, str], dict[tuple[str, str], int]] = {}
    for j in range(2, header.n_cols):
        asset, name = types[j], names[j]
        if asset not in wanted or (asset == "Marker" and name.startswith("Unlabeled")):
            continue
        if not name:
            raise FormatError(
                path, f"column {j + 1} ({asset}) has no name", line=header.row_lines["name"]
            )
        cols = found.setdefault((asset, name), {})
        key = (comps[j], axes[j])
        if key in cols and comps[j] in ("Position", "Rotation"):
            raise FormatError(
                path,
                f"{comps[j]} {axes[j]} appears twice (columns {cols[key] + 1} and {j + 1})",
                line=header.row_lines["axis"],
                where=f"body {name!r}",
            )
        cols.setdefault(key, j)
    specs: list[_BodySpec] = []
    seen: dict[str, str] = {}
    for (asset, name), cols in found.items():
        if name in seen:
            raise FormatError(
                path,
                f"name used by a {seen[name]} and a {asset}",
                line=header.row_lines["name"],
                where=f"body {name!r}",
            )
        seen[name] = asset
        pos = _columns(path, header, name, cols, "Position", "XYZ")
        quat = None
        if asset == "Rigid Body":
            if ("Rotation", "W") not in cols and ("Rotation", "X") in cols:
                raise FormatError(
                    path,
                    "rotation has no W column (Euler angles?); re-export with Rotation Type "
                    "Quaternion",
                    line=header.row_lines["axis"],
                    where=f"body {name!r}",
                )
            quat = _columns(path, header, name, cols, "Rotation", "XYZW")
        first = min(pos)
        specs.append(_BodySpec(name, asset, pos, quat, ids[first]))
    return specs


def _columns(
    path: Path,
    header: _Header,
    name: str,
    cols: Mapping[tuple[str, str], int],
    comp: str,
    axes: str,
) -> list[int]:
    missing = [a for a in axes if (comp, a) not in cols]
    if missing:
        raise FormatError(
            path,
            f"no {comp} {'/'.join(missing)} column; expected {comp} {' '.join(axes)}",
            line=header.row_lines["component"],
            where=f"body {name!r}",
        )
    return [cols[(comp, a)] for a in axes]
