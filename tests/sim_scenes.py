"""A peg-in-hole scene for the physics simulation tests: geometry and a planned run.

The Panda stands at the origin on a table at z = 0; a square plate with a square
hole through it is clamped at (0.5, 0.15); an upright square peg stands at
(0.5, -0.15). The plan picks the peg from above, carries it over the hole and
lowers it straight in until its foot is ``GOAL_Z`` above the table.
"""

from __future__ import annotations

import numpy as np

from thirdhand.execute import Robot, time_parametrize
from thirdhand.simulate.model import CellModel, PartModel
from thirdhand.simulate.parts import convex_hull, convex_pieces, mass_properties
from thirdhand.simulate.plan import PlannedStep, RunPlan, Span
from thirdhand.task.constraint import Constraint

PEG = 0.040  # side, m
PEG_H = 0.100
HOLE = 0.046  # hole side: 3 mm clearance each side
PLATE = 0.140
PLATE_H = 0.030
GOAL_Z = 0.004
GRIP_Z = 0.070  # tool point above the peg's foot
PLATE_AT = np.array([0.5, 0.15, 0.0])
PEG_AT = np.array([0.5, -0.15, 0.0])


def box_mesh(lo, hi) -> np.ndarray:
    from thirdhand.task.meshes import box_triangles

    return box_triangles(lo, hi)


def plate_with_hole() -> np.ndarray:
    """Triangles (n, 3, 3) of a closed square plate with a square hole, plate frame (m)."""
    import trimesh

    o, i = PLATE / 2, HOLE / 2
    outer = [(-o, -o), (o, -o), (o, o), (-o, o)]
    inner = [(-i, -i), (i, -i), (i, i), (-i, i)]
    verts = [(x, y, z) for z in (0.0, PLATE_H) for x, y in outer + inner]
    idx = {(k, z): 8 * z + k for k in range(8) for z in (0, 1)}
    faces = []
    for k in range(4):
        a, b = k, (k + 1) % 4
        oa, ob, ia, ib = a, b, 4 + a, 4 + b
        faces += [(idx[oa, 1], idx[ob, 1], idx[ib, 1]), (idx[oa, 1], idx[ib, 1], idx[ia, 1])]
        faces += [(idx[oa, 0], idx[ib, 0], idx[ob, 0]), (idx[oa, 0], idx[ia, 0], idx[ib, 0])]
        faces += [(idx[oa, 0], idx[ob, 0], idx[ob, 1]), (idx[oa, 0], idx[ob, 1], idx[oa, 1])]
        faces += [(idx[ia, 0], idx[ia, 1], idx[ib, 1]), (idx[ia, 0], idx[ib, 1], idx[ib, 0])]
    mesh = trimesh.Trimesh(np.array(verts), np.array(faces), process=True)
    mesh.fix_normals()
    assert mesh.is_volume
    return np.asarray(mesh.triangles, dtype=np.float64)


def peg_constraint() -> Constraint:
    return Constraint(id="c1", parent="plate", child="peg", type="fixed", pos=(0.0, 0.0, GOAL_Z))


def _pose(at, z=0.0) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = np.asarray(at) + np.array([0.0, 0.0, z])
    return t


def peg_cell(*, hull: bool, density: float = 680.0, cache=None) -> tuple[CellModel, dict]:
    """The cell (plate clamped, peg free) and the parts' corners."""
    plate = plate_with_hole()
    peg = box_mesh([-PEG / 2, -PEG / 2, 0.0], [PEG / 2, PEG / 2, PEG_H])
    pieces = convex_hull(plate) if hull else convex_pieces(plate, name="plate", cache=cache)[0]
    parts = [
        PartModel("plate", pieces, mass_properties(plate, density), _pose(PLATE_AT), fixed=True),
        PartModel("peg", convex_hull(peg), mass_properties(peg, density), _pose(PEG_AT)),
    ]
    corners = {
        "plate": np.array([[x, y, z] for x in (-PLATE / 2, PLATE / 2)
                           for y in (-PLATE / 2, PLATE / 2) for z in (0.0, PLATE_H)]),
        "peg": np.array([[x, y, z] for x in (-PEG / 2, PEG / 2)
                         for y in (-PEG / 2, PEG / 2) for z in (0.0, PEG_H)]),
    }  # fmt: skip
    cell = CellModel("panda", np.eye(4), 0.0, (-0.3, 1.0, -0.6, 0.6), parts, [("peg", "plate")])
    return cell, corners


def _down(at, z) -> np.ndarray:
    """Tool pose pointing down (tool z = world -z), fingers closing along world y."""
    t = np.eye(4)
    t[:3, :3] = np.diag([1.0, -1.0, -1.0])
    t[:3, 3] = np.asarray(at) + np.array([0.0, 0.0, z])
    return t


def _line(robot: Robot, q0, a, b, n=20) -> np.ndarray:
    """Joint path along a straight tool line from pose ``a`` to ``b`` (IK from ``q0``)."""
    out = [q0]
    for s in np.linspace(0.0, 1.0, n)[1:]:
        t = a.copy()
        t[:3, 3] = (1 - s) * a[:3, 3] + s * b[:3, 3]
        q = robot.ik((t[:3, 3], _quat(t)), out[-1], n_restarts=0)
        assert q is not None
        out.append(q)
    return np.array(out)


def _quat(t) -> np.ndarray:
    from thirdhand import se3

    return se3.quat_from_matrix(t[:3, :3])


def peg_plan(*, speed: float = 1.0) -> RunPlan:
    """The pick-carry-insert-retreat run of the peg, time-parametrised at 100 Hz."""
    robot = Robot.load("panda")
    above_peg, at_peg = _down(PEG_AT, 0.25), _down(PEG_AT, GRIP_Z)
    above_hole, in_hole = _down(PLATE_AT, 0.25), _down(PLATE_AT, GRIP_Z + GOAL_Z)
    q_above = robot.ik((above_peg[:3, 3], _quat(above_peg)), robot.home)
    segs = [
        ("approach", np.linspace(robot.home, q_above, 20), None),
        ("grasp", None, None),
        ("lift", None, "peg"),
        ("transport", None, "peg"),
        ("insert", None, "peg"),
        ("retreat", None, None),
    ]
    paths = {"approach": segs[0][1]}
    paths["grasp"] = _line(robot, q_above, above_peg, at_peg)
    paths["lift"] = _line(robot, paths["grasp"][-1], at_peg, above_peg)
    paths["transport"] = _line(robot, paths["lift"][-1], above_peg, above_hole)
    paths["insert"] = _line(robot, paths["transport"][-1], above_hole, in_hole, n=30)
    paths["retreat"] = _line(robot, paths["insert"][-1], in_hole, above_hole)
    ts, qs, spans = [], [], []
    offset = 0.0
    for name, _, attached in segs:
        tr = time_parametrize(paths[name], robot.velocity_limits * speed,
                              robot.acceleration_limits * speed, rate_hz=100.0)  # fmt: skip
        t = tr.t + offset
        ts.append(t)
        qs.append(tr.q)
        spans.append(Span(0, name, float(t[0]), float(t[-1]), attached))
        offset = float(t[-1]) + 0.01
    step = PlannedStep(0, "c1", "plate", "peg", True, "done", "top")
    return RunPlan("panda", np.eye(4), np.concatenate(ts), np.vstack(qs), spans, [step],
                   {"plate": _pose(PLATE_AT), "peg": _pose(PEG_AT)})  # fmt: skip
