"""Settings of the commands: typed records, and ``--config FILE`` to change them.

The command line holds a user's decisions (inputs, outputs, the robot, a seed);
the tuning knobs of a command are fields of a :class:`Settings` record whose
defaults are the best settings the docs report. ``--config FILE`` reads one
TOML, YAML or JSON file with a table per command, named by its path::

    [execute]
    step_time = 120.0
    max_grasps = 48

    [segment.evaluate]
    l2 = 0.5

A command reads only its own table; a file without it leaves every default.
An unknown key, a value of the wrong type or out of range is one
:class:`~thirdhand.errors.OptionError` naming the file, the table and the key.
``thirdhand config`` prints every command's settings with their defaults.
"""

from __future__ import annotations

import importlib
import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, TypeVar

import typer

from thirdhand.errors import OptionError
from thirdhand.readlimits import MAX_CONFIG_BYTES as _MAX_CONFIG_BYTES

if TYPE_CHECKING:
    from thirdhand.settings import Settings

#: Largest configuration file read (bytes): a settings file is a few hundred bytes.
MAX_CONFIG_BYTES = _MAX_CONFIG_BYTES


S = TypeVar("S", bound="Settings")

#: The ``--config FILE`` option every command with settings takes.
ConfigOption = Annotated[
    Path | None,
    typer.Option(
        "--config",
        help="TOML, YAML or JSON file of settings; this command's table "
        "(see `thirdhand config`) changes its defaults.",
    ),
]

#: ``--jobs`` of the commands that run independent units (recordings, seeded runs).
JobsOption = Annotated[int, typer.Option(help="Run the units in this many local processes.")]
#: ``--scheduler`` of the same commands: the units as Dask tasks.
SchedulerOption = Annotated[
    str | None,
    typer.Option(
        help="Run the units as Dask tasks: tcp://HOST:PORT of a 'dask scheduler', or 'local' "
        "(a local cluster of --jobs workers; docs/how-to/cluster.md; needs the dask extra)."
    ),
]


def check_batch(jobs: int, scheduler: str | None) -> None:
    """Refuse a nonsense ``--jobs`` or a malformed ``--scheduler`` before any work."""
    from thirdhand import options

    options.integer("--jobs", jobs, low=1, high=1024)
    if scheduler is not None:
        from thirdhand.batch import check_scheduler

        check_scheduler(scheduler)


#: Command path -> "module:Class" of its settings record (imported only when asked for).
REGISTRY: dict[str, str] = {
    "constraints.fit": "thirdhand.constraints.settings:FitSettings",
    "execute": "thirdhand.execute.settings:ExecuteSettings",
    "simulate": "thirdhand.simulate.settings:SimulateSettings",
    "generate": "thirdhand.generate.settings:GenerateSettings",
    "learn": "thirdhand.learn.settings:LearnSettings",
    "live": "thirdhand.live.settings:LiveSettings",
    "merge": "thirdhand.merge.settings:MergeSettings",
    "synth": "thirdhand.synth.settings:SynthSettings",
    "primitives.fit": "thirdhand.primitives.settings:FitSettings",
    "review": "thirdhand.review.settings:ReviewSettings",
    "segment.train": "thirdhand.segment.settings:TrainSettings",
    "segment.evaluate": "thirdhand.segment.settings:EvaluateSettings",
    "segment.calibrate": "thirdhand.segment.settings:CalibrateSettings",
    "headpose": "thirdhand.perception.settings:HeadposeSettings",
    "gestures": "thirdhand.perception.settings:GestureSettings",
    "attention": "thirdhand.perception.settings:AttentionSettings",
}


def settings_class(command: str) -> type[Settings]:
    """The settings record of ``command`` (a key of :data:`REGISTRY`)."""
    module, _, name = REGISTRY[command].partition(":")
    from thirdhand.settings import Settings

    cls = getattr(importlib.import_module(module), name)
    assert issubclass(cls, Settings)
    return cls


def read_config(path: Path) -> dict[str, Any]:
    """The whole settings file as nested tables (TOML, YAML or JSON by extension).

    Raises
    ------
    OptionError
        Not a regular file, too large, unreadable or not a table of tables.
    """
    from thirdhand.readlimits import check_regular, loads_json, read_input

    where = f"--config {path}"

    def error(message: str) -> OptionError:
        return OptionError(f"{where}: {message}")

    check_regular(path, what="settings file", error=error)
    suffix = path.suffix.lower()
    if suffix not in (".toml", ".yaml", ".yml", ".json"):
        raise error("expected a .toml, .yaml, .yml or .json file")
    raw = read_input(path, what="settings file", limit=MAX_CONFIG_BYTES, error=error)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"not UTF-8 text (byte {exc.start})") from None
    if suffix == ".json":
        data: Any = loads_json(text, error=error, strict=True)
    else:
        try:
            if suffix == ".toml":
                import tomllib

                # TOML itself refuses a key defined twice ("Cannot overwrite a value").
                data = tomllib.loads(text)
            else:
                data = _load_yaml(text)
        except OptionError:
            raise
        except RecursionError:
            raise error("nested too deeply") from None
        except Exception as exc:  # the parsers' own errors (line and column in the message)
            raise error(" ".join(str(exc).split())) from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise OptionError(f"{where}: expected tables of settings, one per command")
    return data


def _load_yaml(text: str) -> Any:
    """YAML with every mapping's keys unique (PyYAML keeps the last of a repeated key)."""
    import yaml

    class _UniqueKeyLoader(yaml.SafeLoader):
        pass

    def mapping(loader: yaml.SafeLoader, node: yaml.MappingNode) -> dict[Any, Any]:
        loader.flatten_mapping(node)
        seen: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            key = loader.construct_object(key_node, deep=True)
            if key in seen:
                raise ValueError(
                    f"line {key_node.start_mark.line + 1}: the key {key!r} is given twice "
                    "in one table"
                )
            seen[key] = loader.construct_object(value_node, deep=True)
        return seen

    _UniqueKeyLoader.add_constructor(
        yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG,
        mapping,
    )
    return yaml.load(text, Loader=_UniqueKeyLoader)


def load_settings(path: Path | None, command: str, cls: type[S]) -> S:
    """``cls`` with its defaults changed by the table ``command`` of the file at ``path``.

    Parameters
    ----------
    path : Path or None
        The ``--config`` file; ``None``: the defaults.
    command : str
        The command's path, dotted (``"segment.evaluate"``).
    cls : type
        Its :class:`Settings` record.
    """
    from pydantic import ValidationError

    if path is None:
        return cls()
    table: Any = read_config(path)
    for key in command.split("."):
        table = table.get(key, {}) if isinstance(table, dict) else None
        if table is None:
            break
    if not isinstance(table, dict):
        raise OptionError(f"--config {path}: [{command}] is not a table of settings")
    try:
        return cls.model_validate(table)
    except ValidationError as exc:
        err = exc.errors()[0]
        key = ".".join(str(p) for p in err["loc"]) or "?"
        if err["type"] == "extra_forbidden":
            known = ", ".join(cls.model_fields)
            raise OptionError(
                f"--config {path}: [{command}] unknown setting {key!r}; expected one of {known}"
            ) from None
        raise OptionError(f"--config {path}: [{command}] {key}: {err['msg']}") from None


def defaults_toml(command: str) -> str:
    """The table of ``command`` with every default, as TOML with each field's description."""
    cls = settings_class(command)
    lines = [f"[{command}]"]
    for name, field in cls.model_fields.items():
        if field.description:
            lines.append(f"# {field.description}")
        value = field.get_default(call_default_factory=True)
        lines.append(f"{name} = {_toml_value(value)}" if value is not None else f"# {name} =")
    return "\n".join(lines)


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, allow_nan=False)
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return json.dumps(str(value), allow_nan=False)
