"""Generate the reference pages of the documentation site from the code (mkdocs-gen-files).

Run by ``mkdocs build`` (the ``gen-files`` plugin in mkdocs.yml); nothing here is
written to the repository. Each page is built from the objects the program itself
uses, so it cannot drift from them:

- ``reference/cli.md``: every command, group and option, walked from the click
  command tree of :mod:`thirdhand.cli` (the lazily imported stage commands too);
- ``reference/settings.md``: every ``--config`` table with its fields, types and
  defaults, from the settings records of :data:`thirdhand.config.REGISTRY`;
- ``reference/task-file-schema.md``: every block and field of the task file, from
  its pydantic models (:class:`thirdhand.task.model.TaskFile` and the stage blocks).

:func:`cli_pages`, :func:`settings_page` and :func:`task_file_page` return the
Markdown text, so tests/test_docs.py checks the same pages the site shows.
"""

from __future__ import annotations

import types
import typing
from collections.abc import Iterator
from typing import Any

#: Title of every generated page, by path under docs/.
PAGES = {
    "reference/cli.md": "Command line",
    "reference/settings.md": "Settings (`--config`)",
    "reference/task-file-schema.md": "Task file fields",
}


# --- the command line -------------------------------------------------------------------------


def command_tree() -> Iterator[tuple[list[str], Any]]:
    """Every command of ``thirdhand`` as (path, click command), groups before their children."""
    import typer

    from thirdhand import cli

    root = typer.main.get_command(cli.app)
    ctx = typer.Context(root, info_name="thirdhand")

    def walk(path: list[str], command: Any) -> Iterator[tuple[list[str], Any]]:
        yield path, command
        if _is_group(command):
            sub_ctx = typer.Context(command, parent=ctx, info_name=path[-1] if path else None)
            for name in command.list_commands(sub_ctx):
                if not path and name in cli.LAZY:
                    child = cli.load_command(name)
                else:
                    child = command.get_command(sub_ctx, name)
                if child is None or child.hidden:
                    continue
                yield from walk([*path, name], child)

    yield from walk([], root)


def _is_group(command: Any) -> bool:
    # typer carries its own copy of click: recognise a group by what it does.
    return hasattr(command, "list_commands")


def _is_argument(param: Any) -> bool:
    return getattr(param, "param_type_name", "") == "argument"


def leaf_commands() -> list[str]:
    """The space-separated paths of every command that runs (no group), e.g. ``segment batch``."""
    return [" ".join(p) for p, c in command_tree() if p and not _is_group(c)]


def _param_row(param: Any) -> str:
    if _is_argument(param):
        name = f"`{param.metavar or (param.name or '').upper()}`"
        kind = "argument" + ("" if param.required else ", optional")
    else:
        names = ", ".join(f"`{o}`" for o in [*param.opts, *param.secondary_opts])
        name = names
        descriptor = getattr(param, "type_descriptor", None)
        annotation = getattr(descriptor, "annotation", None)
        kind = "flag" if param.is_flag else _type_name(annotation) if annotation else "value"
        if param.multiple:
            kind += ", repeatable"
    default = ""
    if not _is_argument(param) and not param.required:
        value = param.default
        if callable(value) or value is None or value == () or (param.is_flag and value is False):
            default = ""
        else:
            default = f"`{value}`"
    if param.required:
        default = "required"
    text = " ".join((getattr(param, "help", None) or "").split()).replace("|", "\\|")
    return f"| {name} | {kind} | {default} | {text} |"


def cli_page() -> str:
    """The Markdown of ``reference/cli.md``: every command with its usage and options."""
    import typer

    lines = [
        "# Command line",
        "",
        "Generated from the command tree of `thirdhand.cli` when the site is built: every "
        "command, its arguments and options, with their defaults. `thirdhand COMMAND --help` "
        "prints the same. The tuning knobs of a command are not options but settings, changed "
        "with `--config FILE`: see [Settings](settings.md).",
        "",
    ]
    for path, command in command_tree():
        if not path:
            continue
        full = " ".join(["thirdhand", *path])
        depth = "#" * min(len(path) + 1, 4)
        lines += [f"{depth} `{full}`", ""]
        help_text = (command.help or command.short_help or "").strip()
        # typer's \b markers (keep the next paragraph as it is) are not Markdown.
        help_text = help_text.replace("\b\n", "").replace("\b", "")
        if help_text:
            lines += [help_text, ""]
        if _is_group(command):
            names = list(command.list_commands(typer.Context(command)))
            lines += ["Commands: " + ", ".join(f"`{full} {n}`" for n in names) + ".", ""]
            if not [p for p in command.params if not getattr(p, "hidden", False)]:
                continue
        ctx = typer.Context(command, info_name=full)
        usage = " ".join(command.collect_usage_pieces(ctx))
        lines += ["```text", f"{full} {usage}", "```", ""]
        params = [p for p in command.params if not getattr(p, "hidden", False)]
        if params:
            lines += ["| parameter | type | default | meaning |", "|---|---|---|---|"]
            lines += [_param_row(p) for p in params]
            lines.append("")
    return "\n".join(lines)


# --- settings ---------------------------------------------------------------------------------


def _type_name(annotation: Any) -> str:
    origin = typing.get_origin(annotation)
    if origin is typing.Literal:
        return " \\| ".join(repr(a) for a in typing.get_args(annotation))
    if origin in (typing.Union, types.UnionType):
        return " \\| ".join(_type_name(a) for a in typing.get_args(annotation))
    if origin is typing.Annotated:
        return _type_name(typing.get_args(annotation)[0])
    if origin is not None:
        args = ", ".join(_type_name(a) for a in typing.get_args(annotation))
        return f"{getattr(origin, '__name__', str(origin))}[{args}]"
    if annotation is type(None):
        return "None"
    return getattr(annotation, "__name__", str(annotation).replace("typing.", ""))


def _default(field: Any) -> str:
    from pydantic_core import PydanticUndefined

    if field.default is PydanticUndefined and field.default_factory is None:
        return "required"
    value = field.get_default(call_default_factory=True)
    if value is None:
        return "unset"
    if hasattr(value, "model_dump"):
        return "(record)"
    return f"`{value!r}`"


def settings_tables() -> list[str]:
    """Every table name of ``--config`` files, dotted (``segment.evaluate``)."""
    from thirdhand.config import REGISTRY

    return list(REGISTRY)


def settings_page() -> str:
    """The Markdown of ``reference/settings.md``: every table, field, type, default."""
    from thirdhand.config import defaults_toml, settings_class

    lines = [
        "# Settings (`--config`)",
        "",
        "Generated from the settings records when the site is built. Every command with "
        "tuning knobs reads one table of a TOML, YAML or JSON file given with `--config FILE`; "
        "a table it does not find leaves every default. The defaults are the best settings "
        "the [Results](../results/index.md) report. `thirdhand config [COMMAND]` prints the "
        "same tables as a file to start from. An unknown key, a wrong type or a value out of "
        "range is one error line naming the file, the table and the key.",
        "",
        "```toml",
        "# my.toml: thirdhand execute task.json --config my.toml",
        "[execute]",
        "step_time = 120.0",
        "",
        "[segment.evaluate]",
        "l2 = 0.5",
        "```",
        "",
    ]
    for table in settings_tables():
        cls = settings_class(table)
        command = "thirdhand " + table.replace(".", " ")
        lines += [
            f"## `[{table}]`",
            "",
            f"Command: `{command}`. Record: `{cls.__module__}.{cls.__name__}`.",
            "",
        ]
        doc = (cls.__doc__ or "").strip().split("\n\n")[0]
        if doc:
            lines += [" ".join(doc.split()), ""]
        lines += ["| key | type | default | meaning |", "|---|---|---|---|"]
        for name, field in cls.model_fields.items():
            text = " ".join((field.description or "").split()).replace("|", "\\|")
            lines.append(
                f"| `{name}` | {_type_name(field.annotation)} | {_default(field)} | {text} |"
            )
        lines += [
            "",
            '??? example "As a file (`thirdhand config ' + table.replace(".", " ") + '`)"',
            "",
            "    ```toml",
        ]
        lines += [f"    {line}" for line in defaults_toml(table).splitlines()]
        lines += ["    ```", ""]
    return "\n".join(lines)


# --- the task file ----------------------------------------------------------------------------


def _models_of(annotation: Any) -> list[type]:
    from pydantic import BaseModel

    found: list[type] = []
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        found.append(annotation)
    for arg in typing.get_args(annotation):
        found += _models_of(arg)
    return found


def _summary(cls: type) -> str:
    doc = (cls.__doc__ or "").strip().split("\n\n")[0]
    return " ".join(doc.split())


def _field_docs(cls: type) -> dict[str, str]:
    """Field descriptions from the numpydoc ``Attributes`` section of a model's docstring."""
    out: dict[str, str] = {}
    lines = (cls.__doc__ or "").splitlines()
    try:
        start = next(i for i, line in enumerate(lines) if line.strip() == "Attributes")
    except StopIteration:
        return out
    indent: int | None = None
    current: list[str] = []
    for line in lines[start + 2 :]:
        if not line.strip():
            continue
        here = len(line) - len(line.lstrip())
        if indent is None:
            indent = here
        if here < indent or line.strip() in ("Notes", "Examples", "See Also"):
            break
        if here == indent:
            current = [n.strip() for n in line.split(":")[0].split(",")]
            for name in current:
                out[name] = ""
        else:
            for name in current:
                out[name] = (out[name] + " " + line.strip()).strip()
    return out


def task_blocks() -> list[str]:
    """The stage blocks of the task file (the fields of ``stages``)."""
    from thirdhand.task.stages import Stages

    return list(Stages.model_fields)


def task_file_page() -> str:
    """The Markdown of ``reference/task-file-schema.md``: every model reachable from the file."""
    from thirdhand.task.model import SCHEMA, TaskFile
    from thirdhand.task.stages import Stages

    lines = [
        "# Task file fields",
        "",
        f'Generated from the pydantic models of the task file (`"schema": "{SCHEMA}"`) when '
        "the site is built: every record reachable from the document, with its fields, types "
        "and defaults. What the file is for and how to edit it: [The task file](task-file.md).",
        "",
        "The stage blocks under `stages`: "
        + ", ".join(f"[`{b}`](#stages-{b})" for b in Stages.model_fields)
        + ".",
        "",
    ]
    seen: set[type] = set()
    queue: list[tuple[str, type]] = [("document", TaskFile)]
    for name, field in Stages.model_fields.items():
        for model in _models_of(field.annotation):
            queue.append((f"stages.{name}", model))
    ordered: list[tuple[str, type]] = []
    while queue:
        where, cls = queue.pop(0)
        if cls in seen:
            continue
        seen.add(cls)
        ordered.append((where, cls))
        for field in cls.model_fields.values():  # type: ignore[attr-defined]
            for model in _models_of(field.annotation):
                if model not in seen:
                    queue.append((f"{cls.__name__}", model))
    for where, cls in ordered:
        anchor = ""
        if where.startswith("stages."):
            anchor = f" {{ #stages-{where.split('.', 1)[1]} }}"
            title = f"`{where}`: `{cls.__name__}`"
        elif where == "document":
            title = "The document: `TaskFile`"
        else:
            title = f"`{cls.__name__}`"
        lines += [f"## {title}{anchor}", ""]
        summary = _summary(cls)
        if summary:
            lines += [summary, ""]
        docs = _field_docs(cls)
        lines += ["| field | type | default | meaning |", "|---|---|---|---|"]
        for name, field in cls.model_fields.items():  # type: ignore[attr-defined]
            key = field.alias or name
            text = field.description or docs.get(name, "") or docs.get(key, "")
            text = " ".join(text.split()).replace("|", "\\|")
            lines.append(
                f"| `{key}` | {_type_name(field.annotation)} | {_default(field)} | {text} |"
            )
        lines.append("")
    return "\n".join(lines)


def main() -> None:
    """Write the generated pages into the site being built (called by mkdocs-gen-files)."""
    import mkdocs_gen_files

    pages = {
        "reference/cli.md": cli_page(),
        "reference/settings.md": settings_page(),
        "reference/task-file-schema.md": task_file_page(),
    }
    for path, text in pages.items():
        with mkdocs_gen_files.open(path, "w") as fh:
            fh.write(text)
        mkdocs_gen_files.set_edit_path(path, "docs/scripts/gen_reference.py")


if __name__ == "<run_path>":  # run by mkdocs-gen-files (runpy.run_path)
    main()
