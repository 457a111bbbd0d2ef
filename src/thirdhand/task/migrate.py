"""Reading task files of earlier schemas: ``thirdhand.task/1`` → ``thirdhand.task/2``.

``thirdhand.task/2`` changed three things:

1. **Typed stage blocks.** In ``/1`` every block of ``stages`` was free-form; in
   ``/2`` the blocks thirdhand writes (``constraints``, ``plan``, ``primitives``,
   ``reward``, ``review``, ``perception``) are validated models
   (:mod:`thirdhand.task.stages`). Their JSON shape did not change, so a ``/1``
   block written by thirdhand reads as it is; one that does not fit its model is
   reported with its JSON location, like any invalid field. Other blocks
   (``transfer``, ``iros15``, ...) are kept as they are.
2. **New blocks** ``scene`` (the scene file the meshes came from), ``grasps``
   (the person's hand on each part at pick-up) and ``execution`` (defaults). A
   migrated ``/1`` file has none: execution then takes grasps from the parts'
   shapes (or ``--demo``), as before.
3. **Mesh paths relative to the task file.** ``/2`` writers record where each
   mesh was found, relative to the task file where possible; ``/1`` files name
   the mesh file only, found beside the task file or along
   ``THIRDHAND_MESH_PATH`` (still looked up that way).

So the migration of a ``/1`` document is its schema string; everything else
reads as it is. The writer always writes ``/2``.
"""

from __future__ import annotations

from typing import Any

from thirdhand.errors import TaskFileError

#: The schema each old schema migrates to, one version at a time.
NEXT_SCHEMA: dict[str, str] = {"thirdhand.task/1": "thirdhand.task/2"}


def migrate(data: dict[str, Any], *, name: str = "<task>") -> dict[str, Any]:
    """The document ``data`` brought to the current schema (a new dict; ``data`` untouched).

    A current document is returned as it is (the same object); a document of an
    unknown schema too (validation names the problem).

    Raises
    ------
    TaskFileError
        If a ``/1`` document's ``stages`` is not an object of objects.
    """
    schema = data.get("schema")
    if not isinstance(schema, str) or schema not in NEXT_SCHEMA:
        return data  # not a schema string, or the current one: validation says which
    out = dict(data)
    while isinstance(out.get("schema"), str) and out["schema"] in NEXT_SCHEMA:
        old = out["schema"]
        if old == "thirdhand.task/1":
            out = _from_v1(out, name)
        out["schema"] = NEXT_SCHEMA[old]
    return out


def _from_v1(data: dict[str, Any], name: str) -> dict[str, Any]:
    stages = data.get("stages", {})
    if not isinstance(stages, dict):
        raise TaskFileError(
            f"{name}: stages: expected an object of stage blocks (thirdhand.task/1)"
        )
    return {**data, "stages": dict(stages)}
