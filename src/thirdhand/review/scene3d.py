"""The review GUI's 3D scene: part meshes, selection colours, free-DOF glyphs.

Pure geometry (:func:`mesh_arrays`, :func:`dof_glyphs`) is separate from the
viser handles (:class:`PartsView`, :class:`DofGlyphView`) so it can be tested
without a browser. Quaternions are x y z w everywhere in thirdhand and w x y z
in viser: :func:`wxyz` converts at the boundary.

Glyphs follow the 3rdHand GUI: a free translation is a thick line along the
constraint-frame axis over its range; a free rotation is an arc about the axis
with arrowheads at its ends: a full joint is a thick closed circle, a limited
one an arc over its range, a noise-level one a thin dashed stub (drawn at a
visible minimum size, since a 2 degree arc would not be seen).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import viser
from numpy.typing import NDArray

from thirdhand.arrays import FloatArray
from thirdhand.se3 import matrix_from_quat
from thirdhand.task.geometry import DOF_NAMES
from thirdhand.task.meshes import box_triangles, object_triangles, resolve_mesh
from thirdhand.task.model import TaskFile

Rgb = tuple[int, int, int]
#: A 3- or 4-vector given as a sequence or an array.
Vector = Sequence[float] | FloatArray

#: The selected object (report: orange).
SELECTED_RGB: Rgb = (255, 140, 0)
#: The selected object's parent (report: blue).
PARENT_RGB: Rgb = (30, 110, 235)
#: Every other part.
DEFAULT_RGB: Rgb = (200, 200, 200)
#: Fingers and hands in playback.
FINGER_RGB: Rgb = (240, 200, 160)
#: Axis colours of the DOF glyphs: x red, y green, z blue (darker blue than the parent's).
AXIS_RGB: tuple[Rgb, Rgb, Rgb] = ((220, 30, 30), (20, 160, 40), (40, 40, 200))
#: Colour of a noise-level rotation glyph.
NOISE_RGB: Rgb = (130, 130, 130)

#: Half size of the box drawn for an object with neither mesh nor bounding box, metres.
FALLBACK_HALF_SIZE = 0.02
#: A rotation glyph spans at least this angle so a noise-level range stays visible, rad.
MIN_GLYPH_ANGLE = np.deg2rad(25.0)


def hex_colour(rgb: Rgb) -> str:
    """``#rrggbb`` of an RGB colour (for the GUI's coloured names)."""
    return "#{:02x}{:02x}{:02x}".format(*rgb)


def wxyz(quat_xyzw: Vector) -> tuple[float, float, float, float]:
    """A quaternion x y z w (thirdhand) as w x y z (viser)."""
    x, y, z, w = (float(v) for v in quat_xyzw)
    return (w, x, y, z)


def xyzw(quat_wxyz: Vector) -> tuple[float, float, float, float]:
    """A quaternion w x y z (viser) as x y z w (thirdhand)."""
    w, x, y, z = (float(v) for v in quat_wxyz)
    return (x, y, z, w)


def _vec3(v: Vector) -> tuple[float, float, float]:
    x, y, z = (float(c) for c in v)
    return (x, y, z)


def mesh_arrays(triangles: FloatArray) -> tuple[FloatArray, NDArray[np.uint32]]:
    """Indexed mesh of a triangle soup, shared corners merged.

    Parameters
    ----------
    triangles : ndarray, shape (n, 3, 3)
        Corners of each triangle, metres, body frame.

    Returns
    -------
    vertices : ndarray, shape (n_vertices, 3)
    faces : ndarray of uint32, shape (n, 3)
        Indices into ``vertices``; winding kept.
    """
    tri = np.asarray(triangles, dtype=np.float64)
    if tri.ndim != 3 or tri.shape[1:] != (3, 3):
        raise ValueError(f"expected triangles of shape (n, 3, 3), got {tri.shape}")
    flat = tri.reshape(-1, 3)
    vertices, inverse = np.unique(np.round(flat, 9), axis=0, return_inverse=True)
    faces = inverse.reshape(-1, 3).astype(np.uint32)
    return vertices, faces


def object_extent(triangles: FloatArray) -> float:
    """Diagonal of the triangles' bounding box, metres."""
    flat = np.asarray(triangles).reshape(-1, 3)
    return float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0)))


@dataclass(frozen=True)
class Glyph:
    """Line segments drawing one free DOF in the constraint frame.

    Attributes
    ----------
    dof : str
        One of :data:`DOF_NAMES`.
    kind : str
        ``"translation"`` or the rotation class (``"full"``, ``"limited"``, ``"noise"``).
    segments : ndarray, shape (n, 2, 3)
        Start and end of each segment, metres, constraint frame.
    rgb : tuple of 3 int
    thickness : float
        Line width, metres (world units).
    """

    dof: str
    kind: str
    segments: FloatArray
    rgb: Rgb
    thickness: float


def _basis(axis: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    e = np.eye(3)
    return e[axis], e[(axis + 1) % 3], e[(axis + 2) % 3]


def _arc_points(axis: int, radius: float, lo: float, hi: float, n: int) -> FloatArray:
    """Points of an arc about ``axis`` from angle ``lo`` to ``hi`` (right-handed), shape (n, 3)."""
    _, u, v = _basis(axis)
    a = np.linspace(lo, hi, n)
    return radius * (np.cos(a)[:, None] * u + np.sin(a)[:, None] * v)


def _arrow_head(axis: int, radius: float, angle: float, sign: float, size: float) -> FloatArray:
    """Two segments of a chevron at ``angle`` on the arc, pointing along ``sign`` * tangent."""
    _, u, v = _basis(axis)
    p = radius * (np.cos(angle) * u + np.sin(angle) * v)
    tangent = sign * (-np.sin(angle) * u + np.cos(angle) * v)
    radial = p / radius
    back = p - size * tangent
    return np.stack([[back + 0.5 * size * radial, p], [back - 0.5 * size * radial, p]])


def dof_glyphs(
    ranges: FloatArray, classes: Sequence[str], *, size: float, max_translation: float = 1.0
) -> list[Glyph]:
    """The glyphs of a constraint's free DOFs, in its constraint frame.

    Parameters
    ----------
    ranges : array_like, shape (6, 2)
        ``[min, max]`` of tx ty tz (m) and rx ry rz (rad).
    classes : sequence of 6 str
        Per DOF: ``"locked"``, ``"noise"``, ``"limited"`` or ``"full"``
        (:func:`thirdhand.review.dofs.classify_dof`). Locked DOFs get no glyph.
    size : float
        Size of the child object, metres: arcs have radius ``0.6 * size``.
    max_translation : float
        Translation lines are clipped to ``[-max_translation, max_translation]``, metres.

    Returns
    -------
    list of Glyph
        In :data:`DOF_NAMES` order.
    """
    r = np.asarray(ranges, dtype=np.float64)
    if r.shape != (6, 2):
        raise ValueError(f"expected DOF ranges of shape (6, 2), got {r.shape}")
    if len(classes) != 6:
        raise ValueError(f"expected 6 DOF classes, got {len(classes)}")
    out: list[Glyph] = []
    thick = max(0.004, 0.04 * size)
    for i, (name, cls) in enumerate(zip(DOF_NAMES, classes, strict=True)):
        if cls == "locked":
            continue
        lo, hi = float(r[i, 0]), float(r[i, 1])
        axis = i % 3
        if i < 3:
            lo_c, hi_c = max(lo, -max_translation), min(hi, max_translation)
            if hi_c - lo_c < 0.2 * size:  # a short range still shows its axis
                mid = 0.5 * (lo_c + hi_c)
                lo_c, hi_c = mid - 0.1 * size, mid + 0.1 * size
            e = np.eye(3)[axis]
            seg = np.stack([[lo_c * e, hi_c * e]])
            out.append(Glyph(name, "translation", seg, AXIS_RGB[axis], thick))
            continue
        radius = 0.6 * size
        head = 0.15 * size
        if cls == "full":
            pts = _arc_points(axis, radius, 0.0, 2 * np.pi, 73)
            segs = np.stack([pts[:-1], pts[1:]], axis=1)
            heads = [_arrow_head(axis, radius, a, 1.0, head) for a in (0.5 * np.pi, 1.5 * np.pi)]
            out.append(
                Glyph(name, "full", np.concatenate([segs, *heads]), AXIS_RGB[axis], 1.5 * thick)
            )
        elif cls == "limited":
            n = max(4, int(np.ceil(abs(hi - lo) / np.deg2rad(5))) + 1)
            pts = _arc_points(axis, radius, lo, hi, n)
            segs = np.stack([pts[:-1], pts[1:]], axis=1)
            heads = [
                _arrow_head(axis, radius, hi, 1.0, head),
                _arrow_head(axis, radius, lo, -1.0, head),
            ]
            out.append(
                Glyph(name, "limited", np.concatenate([segs, *heads]), AXIS_RGB[axis], thick)
            )
        else:  # noise: thin dashes over a visible minimum span
            mid, half = 0.5 * (lo + hi), max(0.5 * (hi - lo), 0.5 * MIN_GLYPH_ANGLE)
            pts = _arc_points(axis, radius, mid - half, mid + half, 9)
            segs = np.stack([pts[:-1:2], pts[1::2]], axis=1)
            out.append(Glyph(name, "noise", segs, NOISE_RGB, 0.4 * thick))
    return out


class PartsView:
    """The task's objects as meshes in a viser scene, one frame per object.

    Parameters
    ----------
    scene : viser.SceneApi
    task : TaskFile
    task_path : path-like or None
        Relative mesh paths are looked up next to it.
    search : sequence of path-like
        More folders searched for meshes (then ``THIRDHAND_MESH_PATH``).
    names : sequence of str, optional
        Objects to draw (default: every part and tool).
    root : str
        Scene-tree prefix.
    """

    def __init__(
        self,
        scene: viser.SceneApi,
        task: TaskFile,
        task_path: str | os.PathLike[str] | None = None,
        search: Sequence[str | os.PathLike[str]] = (),
        *,
        names: Sequence[str] | None = None,
        root: str = "/parts",
    ) -> None:
        self.scene = scene
        self.root = root
        objs = task.objects_by_name()
        if names is None:
            names = [o.name for o in task.objects if o.kind in ("part", "tool", "other")]
        self.names = list(names)
        self.frames: dict[str, viser.FrameHandle] = {}
        self.meshes: dict[str, viser.MeshHandle] = {}
        self.extent: dict[str, float] = {}
        self.centroid: dict[str, FloatArray] = {}
        self.colours: dict[str, Rgb] = {}
        #: Objects whose named mesh file was not found (drawn as their bounding box or a cube).
        self.missing_meshes: dict[str, str] = {}
        self._click: list[Callable[[str, str | None], None]] = []
        for name in self.names:
            obj = objs.get(name)
            tri = None if obj is None else object_triangles(obj, task_path, search)
            if obj is not None and obj.mesh and resolve_mesh(obj, task_path, search) is None:
                self.missing_meshes[name] = str(obj.mesh)
            if tri is None:
                h = FALLBACK_HALF_SIZE
                tri = box_triangles((-h, -h, -h), (h, h, h))
            vertices, faces = mesh_arrays(tri)
            self.extent[name] = object_extent(tri)
            self.centroid[name] = tri.reshape(-1, 3).mean(axis=0)
            frame = scene.add_frame(f"{root}/{name}", show_axes=False)
            mesh = scene.add_mesh_simple(
                f"{root}/{name}/mesh", vertices, faces, color=DEFAULT_RGB, side="double"
            )
            mesh.on_click(self._clicked(name, None))
            mesh.on_click(modifier="shift")(self._clicked(name, "shift"))
            mesh.on_click(modifier="cmd/ctrl")(self._clicked(name, "cmd/ctrl"))
            self.frames[name] = frame
            self.meshes[name] = mesh
            self.colours[name] = DEFAULT_RGB

    def _clicked(self, name: str, modifier: str | None) -> Callable[[object], None]:
        def handler(_event: object) -> None:
            for cb in self._click:
                cb(name, modifier)

        return handler

    def on_click(self, callback: Callable[[str, str | None], None]) -> None:
        """Call ``callback(name, modifier)`` when an object's mesh is clicked in the 3D view.

        ``modifier`` is None for a plain click, ``"shift"`` or ``"cmd/ctrl"`` otherwise.
        """
        self._click.append(callback)

    def set_pose(self, name: str, pos: Vector, quat: Vector) -> None:
        """Place an object: ``pos`` metres, ``quat`` x y z w, world frame."""
        frame = self.frames.get(name)
        if frame is None:
            return
        frame.position = _vec3(pos)
        frame.wxyz = wxyz(quat)

    def set_poses(self, poses: Mapping[str, tuple[Vector, Vector]]) -> None:
        """Place several objects at once (``name -> (pos, quat x y z w)``, world frame)."""
        for name, (pos, quat) in poses.items():
            self.set_pose(name, pos, quat)

    def set_colours(self, colours: Mapping[str, Rgb]) -> None:
        """Recolour objects; unchanged colours are not resent."""
        for name, rgb in colours.items():
            mesh = self.meshes.get(name)
            if mesh is None or self.colours.get(name) == rgb:
                continue
            mesh.color = rgb
            self.colours[name] = rgb

    def world_centroid(self, name: str) -> FloatArray:
        """Mean of the object's mesh corners where it is drawn now, metres, world frame."""
        frame = self.frames[name]
        rot = matrix_from_quat(np.asarray(xyzw(frame.wxyz)))
        return rot @ self.centroid[name] + np.asarray(frame.position, dtype=np.float64)


def floor_height(task: TaskFile, parts: PartsView | None = None) -> float:
    """Height (m, world z) of a floor under the assembled task: its lowest part corner.

    The corners are those of each part's bounding box (or, with ``parts``, its
    drawn mesh) at the assembled pose (:func:`thirdhand.review.dofs.world_poses`);
    0 when no part has a pose.
    """
    from thirdhand.review.dofs import world_poses

    poses = world_poses(task)
    objs = task.objects_by_name()
    lowest = np.inf
    for name, pose in poses.items():
        obj = objs.get(name)
        if obj is None or obj.kind not in ("part", "tool", "other"):
            continue
        if obj.bbox_min is not None and obj.bbox_max is not None:
            lo, hi = np.asarray(obj.bbox_min), np.asarray(obj.bbox_max)
            corners = np.array([[(lo, hi)[b >> k & 1][k] for k in range(3)] for b in range(8)])
        else:
            corners = np.zeros((1, 3))
        world = corners @ matrix_from_quat(np.asarray(pose.quat)).T + np.asarray(pose.pos)
        lowest = min(lowest, float(world[:, 2].min()))
    return 0.0 if not np.isfinite(lowest) else lowest


def selection_colours(
    names: Sequence[str], selected: str | None, parent: str | None
) -> dict[str, Rgb]:
    """Colour of every object: the selected orange, its parent blue, the rest grey."""
    out = {}
    for n in names:
        out[n] = SELECTED_RGB if n == selected else PARENT_RGB if n == parent else DEFAULT_RGB
    return out


def framed_view(
    eye: FloatArray, target: FloatArray, centre: FloatArray, size: float
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """The camera moved to frame one part: same viewing direction, looking at its centre.

    Parameters
    ----------
    eye, target : ndarray, shape (3,), metres, world frame
        The camera's current position and look-at point.
    centre : ndarray, shape (3,), metres, world frame
        The part's centre.
    size : float
        The part's size, metres: the camera stands ``3 × max(size, 0.05)`` from it.

    Returns
    -------
    eye, target : tuple of 3 float
        Metres, world frame.
    """
    c = np.asarray(centre, dtype=np.float64).reshape(3)
    back = np.asarray(eye, dtype=np.float64).reshape(3) - np.asarray(target, dtype=np.float64)
    norm = float(np.linalg.norm(back))
    back = back / norm if norm > 1e-9 else np.array([1.0, -1.0, 0.6]) / np.sqrt(2.36)
    return _vec3(c + 3.0 * max(size, 0.05) * back), _vec3(c)


def front_view(
    centroids: FloatArray, extent: float
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """A camera position and target showing an assembly from its front, z up.

    The front is opposite the highest part (a chair's back) when it stands off
    the centre horizontally, else the (+x, -y) diagonal.

    Parameters
    ----------
    centroids : ndarray, shape (n, 3)
        The parts' centres, metres, world frame.
    extent : float
        The largest part's size, metres (sets the distance).

    Returns
    -------
    eye, target : tuple of 3 float
        Metres, world frame.
    """
    pts = np.asarray(centroids, dtype=np.float64).reshape(-1, 3)
    centre = pts.mean(axis=0) if len(pts) else np.zeros(3)
    away = np.array([1.0, -1.0, 0.0])
    if len(pts):
        off = (pts[np.argmax(pts[:, 2])] - centre) * np.array([1.0, 1.0, 0.0])
        if np.linalg.norm(off) > 0.02:
            away = -off
    away /= np.linalg.norm(away)
    eye = centre + 1.4 * max(extent, 0.2) * (away + np.array([0.0, 0.0, 0.6]))
    return _vec3(eye), _vec3(centre)


class DofGlyphView:
    """The free-DOF glyphs of one constraint, drawn at its constraint frame.

    Parameters
    ----------
    scene : viser.SceneApi
    root : str
        Scene-tree name of the frame holding the glyphs.
    """

    def __init__(self, scene: viser.SceneApi, root: str = "/dofs") -> None:
        self.scene = scene
        self.root = root
        self.anchor = scene.add_frame(root, show_axes=False)
        self._handles: list[viser.LineSegmentsHandle] = []
        self.glyphs: list[Glyph] = []

    def clear(self) -> None:
        """Remove every glyph."""
        for h in self._handles:
            h.remove()
        self._handles = []
        self.glyphs = []

    def show(
        self,
        pos: Vector,
        quat: Vector,
        ranges: FloatArray,
        classes: Sequence[str],
        *,
        size: float,
    ) -> None:
        """Draw the glyphs of ``ranges`` at the constraint frame ``pos``, ``quat`` (xyzw, world)."""
        self.clear()
        self.anchor.position = _vec3(pos)
        self.anchor.wxyz = wxyz(quat)
        self.glyphs = dof_glyphs(ranges, classes, size=size)
        for g in self.glyphs:
            h = self.scene.add_line_segments(
                f"{self.root}/{g.dof}",
                g.segments.astype(np.float32),
                g.rgb,
                thickness=g.thickness,
            )
            self._handles.append(h)
