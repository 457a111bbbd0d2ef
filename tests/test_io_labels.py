"""Label files of the 3rdHand recordings: the kvg syntax, ann_kvg.kvg, ELAN .eaf and its export."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from thirdhand.demonstration import BodyInfo, ConstraintEvent, InteractionInterval
from thirdhand.errors import FormatError
from thirdhand.io import elan, kvg, mlr

N_FRAMES = 22548  # toolbox_3: the labels end at frame 22547


@pytest.fixture
def labels_dir(shared_data: Path) -> Path:
    return shared_data / "3rdhand" / "toolbox_3_labels"


def _raw_entries(path: Path) -> list[tuple[str, str, str, list[tuple[int, int]]]]:
    """ann_kvg.kvg parsed with regular expressions, independently of the reader."""
    out = []
    for line in path.read_text().splitlines():
        m = re.match(r"\s*(TS|CE)\s+(\S+)\s+(\S+)\s*\{", line)
        if m:
            locks = [(int(a), int(b)) for a, b in re.findall(r"from=(\d+)\s+to=(\d+)", line)]
            out.append((m[1], m[2], m[3], locks))
    return out


def _toolbox3_bodies(labels_dir: Path) -> list[BodyInfo]:
    graph = kvg.read(labels_dir / "meta.kvg")
    return [
        mlr.derive_body(e.keys[0], s.keys[0], str(e.value.get("type")))
        for s in graph
        if isinstance(s.value, kvg.Graph)
        for e in s.value
        if isinstance(e.value, kvg.Graph)
    ]


# --------------------------------------------------------------- kvg syntax
def test_kvg_syntax_values() -> None:
    g = kvg.parse(
        "# comment\n"
        'a = { type = "side long", rn = 3, w = 0.5, ok = true, v = [1 2.5, -3e-2] }\n'
        "TS /human/rh /x { lock { from=1 to=2 } }\n"
        "flag\n"
        "b (p q) = word\n"
    )
    assert [n.keys for n in g] == [("a",), ("TS", "/human/rh", "/x"), ("flag",), ("b",)]
    assert [n.line for n in g] == [2, 3, 4, 5]
    sub = g.get("a")
    assert isinstance(sub, kvg.Graph)
    assert sub.to_dict() == {
        "type": "side long",
        "rn": 3,
        "w": 0.5,
        "ok": True,
        "v": (1.0, 2.5, -0.03),
    }
    assert g.get("flag") is None and g.find("flag") is not None
    assert g.find("b") == kvg.Node(("b",), ("p", "q"), "word", 5)


@pytest.mark.parametrize(
    ("text", "line", "pattern"),
    [
        ("a {\n  b = 1\n", 1, "'\\{' opened on line 1 is never closed"),
        ("a { b = 1 }\n}\n", 2, "'\\}' without a matching"),
        ('a = "open\n', 1, "unterminated string"),
        ("a = [1 x 2]\n", 1, "'x' is not a number"),
        ("a = \n}", 2, "expected a value"),
        ("a = { b = [1 2\n", 1, "never closed"),
    ],
)
def test_kvg_syntax_errors(text: str, line: int, pattern: str) -> None:
    with pytest.raises(FormatError, match=pattern) as err:
        kvg.parse(text, "x.kvg")
    assert err.value.line == line
    assert "x.kvg" in str(err.value)


def test_kvg_format_value_round_trips() -> None:
    values = [1, -2.5, 1e-300, 0.1 + 0.2, True, "digit", "two words", 'q"uote', (1.0, 2.0), "12"]
    for v in values:
        back = kvg.parse(f"k = {kvg.format_value(v)}\n").get("k")
        assert back == v and type(back) is type(v)


# --------------------------------------------------------------- real files
def test_toolbox3_meta_parses(labels_dir: Path) -> None:
    bodies = _toolbox3_bodies(labels_dir)
    assert len(bodies) == 11
    assert [b.kind for b in bodies].count("finger") == 6
    assert {b.hand_body for b in bodies if b.kind == "finger"} == {"/human/rh", "/human/lh"}
    assert [b.name for b in bodies if b.kind == "part"] == [
        "/toolbox/side_left",
        "/toolbox/side_front",
        "/toolbox/side_back",
        "/toolbox/side_right",
        "/toolbox/handle",
    ]


def test_toolbox3_kvg_counts_match_raw_text(labels_dir: Path) -> None:
    raw = _raw_entries(labels_dir / "ann_kvg.kvg")
    n_ts = sum(len(lk) for tag, *_, lk in raw if tag == "TS")
    n_ce = sum(len(lk) for tag, *_, lk in raw if tag == "CE")
    assert (sum(tag == "TS" for tag, *_ in raw), sum(tag == "CE" for tag, *_ in raw)) == (10, 10)
    lab = kvg.read_annotations(labels_dir / "ann_kvg.kvg", rate=100.0)
    assert len(lab.interactions) == n_ts == 63
    assert len(lab.constraints) == n_ce == 10
    expected = [
        InteractionInterval(a, b, s / 100.0, e / 100.0)
        for tag, a, b, lk in raw
        if tag == "TS"
        for s, e in lk
    ]
    assert list(lab.interactions) == expected
    assert [(c.time, c.parent, c.child, c.type, c.removed) for c in lab.constraints] == [
        (lk[0][0] / 100.0, a, b, "fixed", False) for tag, a, b, lk in raw if tag == "CE"
    ]


def test_toolbox3_kvg_hands_expand_to_fingers(labels_dir: Path) -> None:
    bodies = _toolbox3_bodies(labels_dir)
    frame_times = 10.0 + np.arange(N_FRAMES) / 40.0
    lab = kvg.read_annotations(labels_dir / "ann_kvg.kvg", frame_times=frame_times, bodies=bodies)
    raw = _raw_entries(labels_dir / "ann_kvg.kvg")
    assert len(lab.interactions) == 3 * sum(len(lk) for tag, *_, lk in raw if tag == "TS")
    assert {i.a for i in lab.interactions} == {b.name for b in bodies if b.kind == "finger"}
    first = raw[0][3][0]
    assert lab.interactions[0] == InteractionInterval(
        "/human/rh/thumb", "/toolbox/side_front", frame_times[first[0]], frame_times[first[1]]
    )
    assert not any(c.removed for c in lab.constraints)


def test_toolbox3_kvg_written_back_byte_identical(labels_dir: Path) -> None:
    ft = np.arange(N_FRAMES) / 100.0
    lab = kvg.read_annotations(labels_dir / "ann_kvg.kvg", frame_times=ft)
    text = kvg.format_annotations(lab, frame_times=ft)
    assert text == (labels_dir / "ann_kvg.kvg").read_text()


def test_toolbox3_elan_matches_its_text_export(labels_dir: Path) -> None:
    from_eaf = elan.read_eaf(labels_dir / "elan.eaf")
    from_txt = elan.read_tab(labels_dir / "ann.txt")
    assert from_eaf == from_txt
    lines = (labels_dir / "ann.txt").read_text().splitlines()
    n_ts, n_ce = (sum(ln.startswith(tag + " ") for ln in lines) for tag in ("TS", "CE"))
    xml = (labels_dir / "elan.eaf").read_text()
    assert xml.count("<ALIGNABLE_ANNOTATION ") == n_ts + n_ce
    assert (len(from_eaf.interactions), len(from_eaf.constraints)) == (n_ts, n_ce) == (63, 10)
    first = from_eaf.interactions[0]
    assert (first.a, first.b, first.start, first.end) == (
        "/human/rh",
        "/toolbox/side_front",
        11.21,
        13.9,
    )


def test_toolbox3_elan_and_kvg_agree_in_structure(labels_dir: Path) -> None:
    """Same tiers, same phases in the same order; a one-to-one monotone frame <-> time map."""
    kv = kvg.parse_annotations(labels_dir / "ann_kvg.kvg")
    el = elan.parse_eaf(labels_dir / "elan.eaf")
    assert [(e.tag, e.a, e.b) for e in kv] == [(e.tag, e.a, e.b) for e in el]
    assert [len(e.spans) for e in kv] == [len(e.spans) for e in el]
    pairs: dict[float, set[float]] = {}
    for ek, ee in zip(kv, el, strict=True):
        for (fs, ft), (ts, te) in zip(ek.spans, ee.spans, strict=True):
            if ek.tag == "CE":
                pairs.setdefault(fs, set()).add(ts)  # CE: only the onset is a label
            else:
                pairs.setdefault(fs, set()).add(ts)
                pairs.setdefault(ft, set()).add(te)
    frames = sorted(pairs)
    times = [min(pairs[f]) for f in frames]
    assert np.all(np.diff(times) > 0)
    spread = {f: max(v) - min(v) for f, v in pairs.items() if len(v) > 1}
    # One annotation (lh/side_left, frame 21036) was typed 10 ms off in ELAN.
    assert spread == {21036.0: pytest.approx(0.01)}
    # The best affine clock (about 40.3 frames per media second) is off by up to 1.6 s:
    # ELAN's media time cannot be mapped onto frames exactly.
    fit = np.polyfit(frames, times, 1)
    assert 1.0 / fit[0] == pytest.approx(40.26, abs=0.05)
    assert 1.0 < np.max(np.abs(np.polyval(fit, frames) - times)) < 2.0


def test_elan_tier_naming_unknown_body_raises(labels_dir: Path) -> None:
    bodies = [b for b in _toolbox3_bodies(labels_dir) if b.name != "/toolbox/handle"]
    with pytest.raises(FormatError, match=r"elan\.eaf line 329.*'/toolbox/handle'") as err:
        elan.read_eaf(labels_dir / "elan.eaf", bodies=bodies)
    assert err.value.line == 329


def test_kvg_naming_unknown_body_raises(labels_dir: Path) -> None:
    bodies = [b for b in _toolbox3_bodies(labels_dir) if not b.name.startswith("/human/lh")]
    with pytest.raises(FormatError, match=r"ann_kvg\.kvg line 6.*'/human/lh'") as err:
        kvg.read_annotations(labels_dir / "ann_kvg.kvg", rate=100, bodies=bodies)
    assert err.value.line == 6


# ---------------------------------------------------------- small synthetic
def test_kvg_removal_and_extensions_round_trip(tmp_path: Path) -> None:
    p = tmp_path / "ann_kvg.kvg"
    p.write_text(
        "CE a b { lock { from=2 to=5 } lock { from=7 to=9 type=prismatic symbol=c3 } }\n"
        "PS a b { step { frame=4 symbol=c3 } }\n"
    )
    ft = np.linspace(0.0, 1.0, 10)
    lab = kvg.read_annotations(p, frame_times=ft)
    assert lab.constraints == (
        ConstraintEvent(ft[2], "a", "b", "fixed"),
        ConstraintEvent(ft[5], "a", "b", "fixed", removed=True),
        ConstraintEvent(ft[7], "a", "b", "prismatic", symbol="c3"),
    )
    assert [(s.parent, s.child, s.symbol, s.time) for s in lab.plan] == [("a", "b", "c3", ft[4])]
    p.write_text(kvg.format_annotations(lab, frame_times=ft))
    assert kvg.read_annotations(p, frame_times=ft) == lab


@pytest.mark.parametrize(
    ("text", "line", "pattern"),
    [
        ("", None, "empty annotation file"),
        ("TS a { lock { from=1 to=2 } }\n", 1, "expected an entry"),
        ("TS a b { lock { from=1 to=2 } }\nXX a b { lock { from=1 to=2 } }\n", 2, "got keys XX"),
        ("TS a b {\n lock { from=3 to=2 }\n}\n", 2, "expected 0 <= from <= to"),
        ("TS a b { lock { from=1 } }\n", 1, "lock to= must be an integer"),
        ("TS a b { lock { from=1.5 to=2 } }\n", 1, "lock from= must be an integer"),
        ("TS a b { hold { from=1 to=2 } }\n", 1, "expected 'lock"),
        ("TS a b { lock { from=1 to=2 }\n", 1, "unbalanced braces"),
    ],
)
def test_kvg_malformed_annotations(
    tmp_path: Path, text: str, line: int | None, pattern: str
) -> None:
    p = tmp_path / "ann_kvg.kvg"
    p.write_text(text)
    with pytest.raises(FormatError, match=pattern) as err:
        kvg.read_annotations(p, rate=100)
    assert err.value.line == line
    assert "ann_kvg.kvg" in str(err.value)


def test_kvg_needs_a_time_base(labels_dir: Path) -> None:
    with pytest.raises(FormatError, match="pass frame_times= or a positive rate="):
        kvg.read_annotations(labels_dir / "ann_kvg.kvg")


def test_elan_malformed(tmp_path: Path) -> None:
    bad = tmp_path / "bad.eaf"
    bad.write_text("<ANNOTATION_DOCUMENT><unclosed></ANNOTATION_DOCUMENT>")
    with pytest.raises(FormatError, match=r"bad\.eaf.*ELAN"):
        elan.read_eaf(bad)
    txt = tmp_path / "ann.txt"
    txt.write_text("TS a b\t\t1.0\t2.0\nTS onlyone\t\t1\t2\n")
    with pytest.raises(FormatError, match="expected 'TS <body a> <body b>'") as err:
        elan.read_tab(txt)
    assert err.value.line == 2
    txt.write_text("TS a b\t\t1.0\tlater\n")
    with pytest.raises(FormatError, match="not seconds"):
        elan.read_tab(txt)


def test_labels_only_folder_is_named_as_such(tmp_path: Path) -> None:
    from thirdhand.io import detect

    (tmp_path / "elan.eaf").write_text("<ANNOTATION_DOCUMENT/>")
    with pytest.raises(FormatError, match=r"holds labels \(elan.eaf\) but no poses.dat"):
        detect(tmp_path)
    (tmp_path / "elan.eaf").unlink()
    with pytest.raises(FormatError, match="unrecognised recording format"):
        detect(tmp_path)
