"""Settings records and ``--config FILE``: defaults, round trips, one error line per bad file."""

from __future__ import annotations

import json
import shlex
import tomllib
from pathlib import Path

import pytest

from cli_helpers import call
from thirdhand import io
from thirdhand.config import REGISTRY, defaults_toml, load_settings, settings_class
from thirdhand.errors import OptionError
from thirdhand.merge.settings import MergeSettings
from thirdhand.settings import Settings
from thirdhand.synth import make_scene


@pytest.fixture(scope="module")
def demo_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("config") / "demo.parquet"
    io.save(make_scene("chair", seed=1, sensor=None).slice(0.0, 2.0), path)
    return path


@pytest.mark.parametrize("command", list(REGISTRY))
def test_printed_defaults_load_back_as_the_defaults(command: str, tmp_path: Path) -> None:
    cls = settings_class(command)
    text = defaults_toml(command)
    path = tmp_path / "defaults.toml"
    path.write_text(text)
    tomllib.loads(text)  # valid TOML
    assert load_settings(path, command, cls) == cls()
    # Every field is documented where a user reads it.
    assert all(f.description for f in cls.model_fields.values()), command


def test_a_table_changes_only_its_command(tmp_path: Path) -> None:
    for suffix, text in (
        (".toml", "[merge]\nmax_gap = 0.5\ndrift = false\n[gestures]\ncone = 10.0\n"),
        (".yaml", "merge:\n  max_gap: 0.5\n  drift: false\ngestures:\n  cone: 10.0\n"),
        (".json", json.dumps({"merge": {"max_gap": 0.5, "drift": False}, "gestures": {}})),
    ):
        path = tmp_path / f"s{suffix}"
        path.write_text(text)
        got = load_settings(path, "merge", MergeSettings)
        assert got == MergeSettings(max_gap=0.5, drift=False)
        assert got.smooth is False and got.rate is None
    # A file without the command's table leaves every default.
    other = tmp_path / "other.toml"
    other.write_text("[attention]\ncone = 5.0\n")
    assert load_settings(other, "merge", MergeSettings) == MergeSettings()
    assert load_settings(None, "merge", MergeSettings) == MergeSettings()


@pytest.mark.parametrize(
    ("name", "text", "fragment"),
    [
        ("s.toml", "[merge]\nmax_gapp = 1\n", "unknown setting 'max_gapp'; expected one of drift"),
        ("s.toml", "[merge]\nmax_gap = -1\n", "[merge] max_gap: Input should be greater than"),
        ("s.toml", "[merge]\nrate = nan\n", "[merge] rate:"),
        ("s.toml", "[merge]\ndrift = 'maybe'\n", "[merge] drift:"),
        ("s.toml", "merge = 3\n", "[merge] is not a table"),
        ("s.toml", "[merge\n", "Expected ']'"),
        ("s.yaml", "- 1\n- 2\n", "expected tables of settings"),
        ("s.json", "[" * 100000 + "]" * 100000, "s.json"),
        ("s.ini", "[merge]\n", "expected a .toml, .yaml, .yml or .json file"),
    ],
)
def test_bad_files_are_one_clear_error(tmp_path: Path, name: str, text: str, fragment: str) -> None:
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(OptionError) as err:
        load_settings(path, "merge", MergeSettings)
    message = str(err.value)
    assert "\n" not in message and fragment in message and str(path) in message


def test_not_a_file_and_too_large(tmp_path: Path) -> None:
    with pytest.raises(OptionError, match="is a folder, not a settings file"):
        load_settings(tmp_path, "merge", MergeSettings)
    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * (2 << 20))
    with pytest.raises(OptionError, match="a settings file of more than 1 MiB is refused"):
        load_settings(big, "merge", MergeSettings)
    with pytest.raises(OptionError, match="is a device, not a settings file"):
        load_settings(Path("/dev/zero"), "merge", MergeSettings)


def test_settings_are_immutable() -> None:
    s = MergeSettings()
    with pytest.raises(ValueError, match="frozen"):
        s.max_gap = 3.0  # type: ignore[misc]
    assert isinstance(s, Settings)


#: (command with {demo} and {cfg}, the settings file's text, a fragment of the error line)
CLI_CASES: list[tuple[str, str, str]] = [
    ("segment train {demo} -o {dir}/m.json --config {cfg}", "[segment.train]\nwindow = 0\n",
     "[segment.train] window"),
    ("segment train {demo} -o {dir}/m.json --config {cfg}",
     "[segment.train]\nlatent_rate = inf\n", "[segment.train] latent_rate"),
    ("segment evaluate {demo} --config {cfg}", "[segment.evaluate]\ntrain_hand = 'middle'\n",
     "[segment.evaluate] train_hand"),
    ("gestures {demo} --config {cfg}", "[gestures]\ncone = -5.0\n", "[gestures] cone"),
    ("gestures {demo} --config {cfg}", "[gestures]\ncone = nan\n", "[gestures] cone"),
    ("gestures {demo} --config {cfg}", "[gestures]\ndwell = -1.0\n", "[gestures] dwell"),
    ("gestures {demo} --config {cfg}", "[gestures]\ndwell = 1e9\n", "[gestures] dwell"),
    ("gestures {demo} --config {cfg}", "[gestures]\nray = 'sideways'\n", "[gestures] ray"),
    ("attention {demo} --config {cfg}", "[attention]\nforward = [nan, 0, 0]\n",
     "[attention] forward"),
    ("attention {demo} --config {cfg}", "[attention]\nforward = [0, 0, 0]\n",
     "not all zero"),
    ("attention {demo} --config {cfg}", "[attention]\ncone = inf\n", "[attention] cone"),
    ("attention {demo} --config {cfg}", "[attention]\nmin_duration = -1\n",
     "[attention] min_duration"),
    ("headpose {demo} --config {cfg}", "[headpose]\nstart = 5\nstop = 2\n",
     "expected a frame after start = 5"),
    ("merge {demo} {dir}/b.parquet -o {dir}/m.parquet --config {cfg}", "[merge]\nsmoth = true\n",
     "unknown setting 'smoth'"),
    ("primitives fit {demo} -o {dir}/p.json --config {cfg}",
     "[primitives.fit]\npromp_weights = -3\n",
     "[primitives.fit] promp_weights"),
    ("primitives fit {demo} -o {dir}/p.json --config {cfg}", "[primitives.fit]\nweights = 0\n",
     "[primitives.fit] weights"),
    ("primitives fit {demo} -o {dir}/p.json --config {cfg}",
     "[primitives.fit]\nalign = 'sideways'\n",
     "[primitives.fit] align"),
    ("synth chair -o {dir}/x.csv --config {cfg}", "[synth]\npointing = 100000\n",
     "[synth] pointing"),
    ("synth chair -o {dir}/x.csv --config {cfg}", "[synth]\npointing = -1\n", "[synth] pointing"),
    ("config nosuch", "", "'nosuch' has no settings"),
]  # fmt: skip


@pytest.mark.parametrize(("template", "text", "fragment"), CLI_CASES)
def test_bad_settings_are_one_error_line(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    demo_file: Path,
    template: str,
    text: str,
    fragment: str,
) -> None:
    cfg = tmp_path / "settings.toml"
    cfg.write_text(text)
    args = shlex.split(template.format(demo=demo_file, dir=tmp_path, cfg=cfg))
    rc, out, err = call(capsys, *args)
    assert rc in (1, 2), (args, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("thirdhand: error: "), err
    assert fragment in lines[0], lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["settings.toml"]


def test_config_command_prints_every_table(capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, err = call(capsys, "config")
    assert rc == 0, err
    doc = tomllib.loads(out)
    for command in REGISTRY:
        table = doc
        for key in command.split("."):
            table = table[key]
        assert set(table) <= set(settings_class(command).model_fields)
    rc, out, _ = call(capsys, "config", "segment evaluate")
    assert rc == 0 and out.startswith("[segment.evaluate]")


def _leaf_commands() -> list[tuple[str, object]]:
    """Every leaf command of ``thirdhand``, through typer's click API, lazy groups loaded."""
    import typer

    from thirdhand.cli import LAZY, app, load_command

    def leaves(cmd: object, path: tuple[str, ...]) -> list[tuple[str, object]]:
        if hasattr(cmd, "list_commands"):
            ctx = typer.main.get_command(app).make_context("thirdhand", [], resilient_parsing=True)
            out: list[tuple[str, object]] = []
            for name in cmd.list_commands(ctx):  # type: ignore[attr-defined]
                top = not path and name in LAZY
                sub = load_command(name) if top else cmd.get_command(ctx, name)  # type: ignore[attr-defined]
                out += leaves(sub, (*path, name))
            return out
        return [(" ".join(path), cmd)]

    return leaves(typer.main.get_command(app), ())


def test_the_command_line_is_small() -> None:
    """At most 10 options per command and 125 in all (help excluded): knobs are settings."""
    counts = {
        name: sum(
            1
            for p in cmd.params  # type: ignore[attr-defined]
            if getattr(p, "param_type_name", "") == "option" and p.name != "help"
        )
        for name, cmd in _leaf_commands()
    }
    assert len(counts) >= 20 and "execute" in counts and "segment evaluate" in counts
    assert max(counts.values()) <= 10, counts
    assert sum(counts.values()) <= 125, counts
