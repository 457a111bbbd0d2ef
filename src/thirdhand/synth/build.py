"""``make_scene``: script the cycles, evaluate the timeline, pass it through the sensor.

Several assembly cycles (``cycles=`` or ``duration=``) are joined by disassembly:
each disassembly is the preceding assembly played backwards in time (unscrewing,
pulling out, laying the parts back where they were), so every cycle starts from
the same layout with the bodies where the last one left them and every trajectory
stays continuous. A disassembly removes each constraint at the mirror image of
the time it was made (``ConstraintEvent(removed=True)``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from thirdhand.demonstration import (
    ConstraintEvent,
    Demonstration,
    InteractionInterval,
    Labels,
    PlanStep,
)
from thirdhand.errors import ThirdhandError
from thirdhand.synth import extra_scenes, scenes
from thirdhand.synth.engine import Segment, Timeline
from thirdhand.synth.human import HumanModel
from thirdhand.synth.pointing import add_pointing
from thirdhand.synth.script import Sim
from thirdhand.synth.sensor import SensorModel

Script = Callable[[Sim, scenes.Layout, np.random.Generator], float]
LayoutFn = Callable[..., scenes.Layout]

_SCENES: dict[str, tuple[LayoutFn, Script, dict[str, Any]]] = {
    "chair": (scenes.layout_chair, scenes.script_chair, {"bench": False}),
    "bench": (scenes.layout_chair, scenes.script_chair, {"bench": True}),
    "toolbox": (extra_scenes.layout_toolbox, extra_scenes.script_toolbox, {}),
    "drawer": (extra_scenes.layout_drawer, extra_scenes.script_drawer, {}),
    "lid": (extra_scenes.layout_lid, extra_scenes.script_lid, {}),
}
SCENES: tuple[str, ...] = tuple(_SCENES)
_OPTIONS = ("duration", "cycles", "head", "pointing")


def make_scene(
    name: str,
    *,
    seed: int = 0,
    sensor: SensorModel | None = SensorModel(),  # noqa: B008 - frozen, immutable default
    n_people: int = 1,
    human: HumanModel | None = None,
    **scene_options: Any,
) -> Demonstration:
    """A synthetic demonstration of one scene with exact ground-truth labels.

    Parameters
    ----------
    name : {"chair", "bench", "toolbox", "drawer", "lid"}
    seed : int
        Seeds everything: the same seed gives a bit-identical demonstration.
    sensor : SensorModel or None
        Noise, gaps and sign flips; None gives the true poses at 120 Hz.
    n_people : {1, 2}
        With 2, the second person (bodies ``p2_…``) holds the parts.
    human : HumanModel, optional
        How much the hands move when they wait and when they hold a part
        (:class:`~thirdhand.synth.human.HumanModel`); default: the synthetic
        human's usual sway and wobble (a waiting hand is never still).
    **scene_options
        ``duration`` (float): seconds to fill with repeated assembly/disassembly
        cycles; the recording is cut there. ``cycles`` (int): number of assemblies
        (disassemblies in between); default 1. ``head`` (bool): also track each
        person's head (bodies ``head``, ``p2_head``). ``pointing`` (int): open with
        that many pointing gestures (one cycle only; ground truth in
        ``meta["pointing"]``, see :mod:`thirdhand.synth.pointing`).

    Returns
    -------
    Demonstration
        ``labels`` hold the interactions, constraints and plan; ``meta`` the scene,
        seed, sensor parameters and per-object geometry.

    Raises
    ------
    ThirdhandError
        Unknown scene or option, or an option out of range.
    """
    if name not in _SCENES:
        raise ThirdhandError(f"unknown scene {name!r}; scenes are {', '.join(SCENES)}")
    unknown = set(scene_options) - set(_OPTIONS)
    if unknown:
        raise ThirdhandError(
            f"scene {name!r}: unknown option(s) {', '.join(sorted(unknown))}; "
            f"options are {', '.join(_OPTIONS)}"
        )
    if n_people not in (1, 2):
        raise ThirdhandError(f"scene {name!r}: n_people must be 1 or 2, got {n_people}")
    duration = scene_options.get("duration")
    cycles = scene_options.get("cycles")
    if duration is not None and not float(duration) > 0:
        raise ThirdhandError(f"scene {name!r}: duration must be > 0 s, got {duration}")
    if cycles is not None and (int(cycles) != cycles or cycles < 1):
        raise ThirdhandError(f"scene {name!r}: cycles must be a positive integer, got {cycles}")
    pointing = int(scene_options.get("pointing") or 0)
    if pointing and (duration is not None or (cycles or 1) > 1 or pointing < 0):
        raise ThirdhandError(f"scene {name!r}: pointing needs one cycle and a count >= 0")
    pointed: list[dict[str, Any]] = []
    layout_fn, script, fixed = _SCENES[name]
    scene_rng, sensor_rng = np.random.default_rng(seed).spawn(2)
    layout = layout_fn(scene_rng, n_people=n_people, head=bool(scene_options.get("head")), **fixed)

    sims: list[Sim] = []
    total = 0.0
    while True:
        sim = layout.new_sim(scene_rng)
        if human is not None:
            human.apply(sim.hands.values())
        for screw, part in layout.extra.get("preinserted", []):
            sim.pair(part, screw, 0.0)
        sim.finish(script(sim, layout, scene_rng))
        if pointing:
            sim, pointed = add_pointing(
                sim, layout, np.random.default_rng(seed).spawn(3)[2], pointing
            )
        sims.append(sim)
        total += sim.end if len(sims) == 1 else 2 * sim.end
        if duration is not None and total >= float(duration):
            break
        if duration is None and len(sims) >= (cycles or 1):
            break
        if len(sims) > 100_000:
            raise ThirdhandError(f"scene {name!r}: cycles never reach {duration} s")

    timeline, labels, end, holds = _join(sims)
    if duration is not None:
        end = float(duration)
    rate = sensor.rate if sensor is not None else 120.0
    t = np.arange(int(np.floor(end * rate + 1e-9)) + 1) / rate
    infos = list(sims[0].bodies.values())
    names = [b.name for b in infos]
    poses = timeline.evaluate(t, names)
    pos: dict[str, Any] = {}
    quat: dict[str, Any] = {}
    valid: dict[str, Any] = {}
    # Hub dropouts and stamp jitter draw from their own stream: a sensor without
    # them sees exactly what it saw before they existed.
    hub_rng = np.random.default_rng([seed, 7919])
    hubs: dict[str, Any] = {}
    for info in infos:
        p, q = poses[info.name]
        if sensor is not None:
            hub = (info.hand_body or info.name) if info.kind == "finger" else "objects"
            if info.kind not in ("finger", "part", "tool"):
                hub = info.name
            if sensor.dropout_rate > 0 and hub not in hubs:
                hubs[hub] = sensor.dropouts(t.size, hub_rng)
            p, q, v = sensor.observe(t, p, q, info.kind, sensor_rng, delivered=hubs.get(hub))
        else:
            v = np.ones(t.size, dtype=bool)
        pos[info.name], quat[info.name], valid[info.name] = p, q, v
    if sensor is not None:
        t = sensor.stamps(t, hub_rng)
    meta = {
        "source": "thirdhand.synth",
        "scene": name,
        "seed": seed,
        "n_people": n_people,
        "cycles": len(sims),
        "options": {k: scene_options[k] for k in sorted(scene_options)},
        "sensor": None if sensor is None else sensor.to_meta(),
        "human": None if human is None else human.to_meta(),
        "units": "m",
        "up_axis": "z",
        "table_z_m": scenes.TABLE_Z,
        "geometry": layout.meta,
        # When each finger holds an object (contact, whether or not it moves it:
        # the interaction labels keep only the manipulation), seconds.
        "holds": [[i.a, i.b, i.start, min(i.end, float(t[-1]))] for i in holds if i.start <= t[-1]],
    }
    if pointed:
        meta["pointing"] = pointed
    return Demonstration(t, infos, pos, quat, valid, labels=_clip(labels, float(t[-1])), meta=meta)


def random_scene(name: str, seed: int, *, geometry: bool = True) -> Demonstration:
    """A scene seen through a random sensor and done by a random person (seeded).

    The realistic synthetic world the shipped segmentation model is trained on:
    :meth:`SensorModel.random` (10 µm–1 mm, 20–120 Hz, hub dropouts, stamp
    jitter) and :meth:`HumanModel.random` (still or swaying rests, hold wobble,
    a flexing grip), both drawn from ``seed``; ``geometry=False`` withholds the
    parts' bounding boxes, as most real recordings come without meshes.
    """
    rng = np.random.default_rng([seed, 31337])
    sensor, human = SensorModel.random(rng), HumanModel.random(rng)
    demo = make_scene(name, seed=seed, sensor=sensor, human=human)
    if not geometry:
        demo = demo.replace(meta={**demo.meta, "geometry": {}})
    return demo


def _join(sims: list[Sim]) -> tuple[Timeline, Labels, float, list[InteractionInterval]]:
    """Concatenate cycles, each but the last followed by its time reversal.

    Returns the timeline, the labels, the end time and the holds (when each
    finger holds an object, :attr:`Sim.grasps`), joined like the interactions.
    """
    timeline = Timeline()
    inter: list[InteractionInterval] = []
    holds: list[InteractionInterval] = []
    cons: list[ConstraintEvent] = []
    plan: list[PlanStep] = []
    origin = 0.0
    for k, sim in enumerate(sims):
        length = sim.end
        for body, segs in sim.timeline.segments.items():
            for s in segs:
                timeline.add(body, _shift(s, origin, 1.0, origin + s.start))
        inter += [dataclasses.replace(i, start=i.start + origin, end=i.end + origin)
                  for i in sim.interactions]  # fmt: skip
        grasps = [InteractionInterval(f, o, s, e) for f, o, s, e in sim.grasps]
        holds += [InteractionInterval(i.a, i.b, i.start + origin, i.end + origin) for i in grasps]
        cons += [dataclasses.replace(c, time=c.time + origin) for c in sim.constraints]
        plan += [dataclasses.replace(p, time=(p.time or 0.0) + origin) for p in sim.plan]
        if k == len(sims) - 1:
            origin += length
            break
        mirror = origin + 2 * length
        for body, segs in sim.timeline.segments.items():
            ends = [s.start for s in segs[1:]] + [length]
            for s, e in zip(reversed(segs), reversed(ends), strict=True):
                timeline.add(body, _shift(s, mirror, -1.0, mirror - e))
        inter += [dataclasses.replace(i, start=mirror - i.end, end=mirror - i.start)
                  for i in sim.interactions]  # fmt: skip
        holds += [InteractionInterval(i.a, i.b, mirror - i.end, mirror - i.start) for i in grasps]
        cons += [dataclasses.replace(c, time=mirror - c.time, removed=True)
                 for c in reversed(sim.constraints)]  # fmt: skip
        origin = mirror
    cons.sort(key=lambda c: c.time)
    labels = Labels(tuple(_merge(inter)), tuple(cons), tuple(plan))
    return timeline, labels, origin, _merge(holds)


def _shift(seg: Segment, origin: float, sign: float, start: float) -> Segment:
    """``seg`` placed at ``start``, its global time ``t`` read as ``sign (t − origin)``."""
    # local = off + sgn * (sign * (t - origin))
    return Segment(
        start=start,
        motion=seg.motion,
        parent=seg.parent,
        t_offset=seg.t_offset - seg.t_sign * sign * origin,
        t_sign=seg.t_sign * sign,
    )


def _merge(items: list[InteractionInterval]) -> list[InteractionInterval]:
    """Join intervals of the same pair that touch (a part–part pair across a cycle's end)."""
    by_pair: dict[tuple[str, str], list[InteractionInterval]] = {}
    for i in items:
        by_pair.setdefault((i.a, i.b), []).append(i)
    out: list[InteractionInterval] = []
    for group in by_pair.values():
        group.sort(key=lambda i: i.start)
        cur = group[0]
        for nxt in group[1:]:
            if nxt.start <= cur.end + 1e-9:
                cur = dataclasses.replace(cur, end=max(cur.end, nxt.end))
            else:
                out.append(cur)
                cur = nxt
        out.append(cur)
    out.sort(key=lambda i: (i.start, i.a, i.b))
    return out


def _clip(labels: Labels, end: float) -> Labels:
    """Labels restricted to ``[0, end]`` seconds."""
    return Labels(
        interactions=tuple(
            dataclasses.replace(i, end=min(i.end, end))
            for i in labels.interactions
            if i.start <= end
        ),
        constraints=tuple(c for c in labels.constraints if c.time <= end),
        plan=tuple(p for p in labels.plan if p.time is not None and p.time <= end),
    )
