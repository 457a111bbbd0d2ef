"""Figures of learnt skills and parses (matplotlib, Agg backend; nothing is shown)."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from thirdhand.arrays import FloatArray
from thirdhand.primitives.primitive_library import Parse, PrimitiveLibrary
from thirdhand.primitives.quaternion_dmp import PoseDMP


def plot_library(
    library: PrimitiveLibrary,
    path: str | os.PathLike[str],
    *,
    tracks: Sequence[tuple[FloatArray, FloatArray]] = (),
    n_samples: int = 20,
    seed: int = 0,
) -> None:
    """Samples from each skill's ProMP (normalised segment frame) and parsed tracks.

    Parameters
    ----------
    library : PrimitiveLibrary
        Fitted.
    path : path-like
        PNG (or any matplotlib format) to write.
    tracks : sequence of (t (n,), y (n, dims)), optional
        Drawn below the skills, coloured by the skill of each parsed segment.
    n_samples : int
        Trajectories sampled per skill.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    skills = library.skills()
    k = len(skills)
    rows = 1 + len(tracks)
    fig, axes = plt.subplots(rows, k, figsize=(3.2 * k, 2.6 * rows), squeeze=False)
    z = np.linspace(0.0, 1.0, 60)
    colours = plt.get_cmap("tab10")
    for i, sk in enumerate(skills):
        ax = axes[0, i]
        samples = sk.sample(z, n_samples, rng=seed + i)
        mean = sk.mean_trajectory(z)
        if sk.dims_ == 1:
            ax.plot(z, samples[:, :, 0].T, color=colours(i), alpha=0.3, lw=0.8)
            ax.plot(z, mean[:, 0], color="k", lw=1.5)
            ax.set_xlabel("phase")
        else:
            for s in samples:
                ax.plot(s[:, 0], s[:, 1], color=colours(i), alpha=0.3, lw=0.8)
            ax.plot(mean[:, 0], mean[:, 1], color="k", lw=1.5)
            ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(f"skill {i} (π = {library.mixture_.weights_[i]:.2f})")
    for r, (t, y) in enumerate(tracks, start=1):
        parse = library.parse(t, y)
        ax = axes[r, 0]
        _draw_parse(ax, np.asarray(t), np.asarray(y), parse, colours)
        for extra in axes[r, 1:]:
            extra.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _draw_parse(ax: object, t: FloatArray, y: FloatArray, parse: Parse, colours: object) -> None:
    y2 = y[:, None] if y.ndim == 1 else y
    for (a, b), lab in zip(
        zip(parse.bounds[:-1], parse.bounds[1:], strict=True), parse.labels, strict=True
    ):
        if y2.shape[1] == 1:
            ax.plot(t[a : b + 1], y2[a : b + 1, 0], color=colours(int(lab)))  # type: ignore[attr-defined, operator]
        else:
            ax.plot(y2[a : b + 1, 0], y2[a : b + 1, 1], color=colours(int(lab)))  # type: ignore[attr-defined, operator]
    for c in parse.candidates:
        if y2.shape[1] == 1:
            ax.axvline(t[c], color="0.8", lw=0.5, zorder=0)  # type: ignore[attr-defined]
    ax.set_title(f"parse: {len(parse.labels)} segments of {len(parse.candidates) + 1}")  # type: ignore[attr-defined]


def plot_generalisation(
    dmp: PoseDMP,
    path: str | os.PathLike[str],
    *,
    goal_pos: FloatArray,
    goal_quat: FloatArray,
    offsets: FloatArray,
    demo_pos: FloatArray | None = None,
    title: str = "",
) -> None:
    """Fig. 4 of the report: rollouts from shifted starts, all reaching the constraint pose.

    Parameters
    ----------
    dmp : PoseDMP
        Fitted, in the parent frame.
    goal_pos : ndarray, shape (3,), metres, parent frame
    goal_quat : ndarray, shape (4,), x y z w, parent frame
    offsets : ndarray, shape (k, 3)
        Start shifts, metres.
    demo_pos : ndarray, shape (n, 3), optional
        The averaged demonstration, drawn dashed.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9, 4))
    run = 1.5 * dmp.position_.tau_
    for o in np.atleast_2d(offsets):
        _, p, _ = dmp.position_.rollout(start=dmp.position_.start_ + o, goal=goal_pos, run_time=run)
        axes[0].plot(p[:, 0], p[:, 2], lw=0.8)
        axes[1].plot(p[:, 0], p[:, 1], lw=0.8)
    if demo_pos is not None:
        axes[0].plot(demo_pos[:, 0], demo_pos[:, 2], "k--", lw=1.2, label="demonstration")
        axes[1].plot(demo_pos[:, 0], demo_pos[:, 1], "k--", lw=1.2)
        axes[0].legend(loc="best", fontsize=8)
    for ax, (a, b) in zip(axes, (("x", "z"), ("x", "y")), strict=True):
        ax.plot(goal_pos[0], goal_pos[2 if b == "z" else 1], "r*", ms=12)
        ax.set_xlabel(f"{a} (m, parent frame)")
        ax.set_ylabel(f"{b} (m)")
        ax.set_aspect("equal", adjustable="datalim")
    fig.suptitle(title or "rollouts from shifted starts to the constraint pose")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_skill_parses(
    tracks: Sequence[object],
    parses: Sequence[object],
    path: str | os.PathLike[str],
    *,
    max_tracks: int = 6,
) -> None:
    """Each track's position over time, coloured by the skill of every sample.

    Parameters
    ----------
    tracks : sequence of PoseTrack
    parses : sequence of TrackParse
        One per track (:meth:`~thirdhand.primitives.skill_library.SkillLibrary.parse`).
    path : path-like
        PNG (or any matplotlib format) to write.
    max_tracks : int
        At most this many tracks are drawn.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = max(min(len(tracks), max_tracks), 1)
    fig, axes = plt.subplots(rows, 1, figsize=(9, 2.2 * rows), squeeze=False)
    colours = plt.get_cmap("tab10")
    for ax, tr, p in zip(axes[:, 0], tracks, parses, strict=False):
        t, pos = tr.t, tr.pos - tr.pos[0]  # type: ignore[attr-defined]
        labels = p.labels  # type: ignore[attr-defined]
        for c, style in zip(range(3), ("-", "--", ":"), strict=True):
            ax.plot(t, pos[:, c], color="0.75", lw=0.8, ls=style)
        for s, e, k in zip(
            p.starts,  # type: ignore[attr-defined]
            [*p.starts[1:], labels.size],  # type: ignore[attr-defined]
            p.skills,  # type: ignore[attr-defined]
            strict=True,
        ):
            ax.axvspan(t[s], t[min(e, t.size - 1)], color=colours(int(k) % 10), alpha=0.25, lw=0)
        ax.set_ylabel("x y z − start, m")
        ax.set_title(str(tr.name)[-60:], fontsize=8)  # type: ignore[attr-defined]
    axes[-1, 0].set_xlabel("time, s")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
