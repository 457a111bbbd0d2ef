"""Settings of ``thirdhand simulate`` (``[simulate]`` of ``--config``).

The defaults are the ones ``docs/how-to/simulate.md`` measures: a friction grasp with the
Franka Hand's continuous force, parts of plywood density, collision geometry from
a convex decomposition of each mesh.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from thirdhand.settings import Settings


class SimulateSettings(Settings):
    """How the physics simulation of a planned run is built, driven and judged."""

    robot: str | None = Field(
        None, description="Robot planned and simulated (default: the task's, else panda)."
    )
    seed: int = Field(0, ge=0, le=2**31 - 1, description="Seed of the start layout and planner.")
    grasp: Literal["friction", "weld"] = Field(
        "friction",
        description="friction: the fingers close with the gripper's force limit and the part "
        "is carried by contact; weld: the part is welded to the hand when the fingers close.",
    )
    collision: Literal["exact", "decomposition", "hull"] = Field(
        "exact",
        description="Collision geometry of a part mesh: exact (its convex hull with its "
        "pockets, grooves and notches cut out exactly; a mesh that is not a closed surface "
        "falls back to decomposition), decomposition (CoACD's approximate convex "
        "decomposition: its pieces bulge about a millimetre into pockets) or hull (the "
        "convex hull: holes filled).",
    )
    density: float = Field(
        680.0, gt=0.0, le=50_000.0, description="Density of every part, kg/m³ (plywood)."
    )
    friction: float = Field(
        0.8, gt=0.0, le=5.0, description="Sliding friction coefficient of the finger pads."
    )
    part_friction: float = Field(
        0.4, gt=0.0, le=5.0, description="Sliding friction coefficient of the parts and table."
    )
    gripper_force: float = Field(
        70.0,
        gt=0.0,
        le=1000.0,
        description="Force limit of each finger, N (the Franka Hand's continuous force).",
    )
    aim: bool = Field(
        True,
        description="Re-aim the arm at the part as it sits in the hand (measured after the "
        "fingers close and during the carry, as the cell's motion capture tracks the parts), "
        "so that the part follows its planned path; false replays the plan as planned.",
    )
    slowdown: float = Field(
        2.0,
        ge=1.0,
        le=20.0,
        description="The planned motions replayed this many times slower. The planner times "
        "them at the arm's joint speed limits; at half that speed the arm stays within its "
        "limits with the re-aim's corrections on top (at 1 it reaches 1.4 times them).",
    )
    timestep: float = Field(0.002, gt=0.0, le=0.01, description="Physics time step, seconds.")
    close_time: float = Field(
        0.6, gt=0.0, le=10.0, description="Seconds the arm waits while the fingers close."
    )
    open_time: float = Field(
        0.4, gt=0.0, le=10.0, description="Seconds the arm waits while the fingers open."
    )
    seat_time: float = Field(
        2.0,
        ge=0.0,
        le=60.0,
        description="Longest seconds the arm holds the end of an insertion while the part "
        "has not reached its goal, re-aiming it across its insertion axis (a leg on the rim "
        "of its pocket slides in); 0: the fastening follows the insertion at once.",
    )
    fasten_time: float = Field(
        0.3, ge=0.0, le=60.0, description="Seconds the person takes to fasten a placed part."
    )
    rest_time: float = Field(
        2.0, ge=0.0, le=60.0, description="Seconds the assembly rests after the last step."
    )
    position_tolerance: float = Field(
        5.0, gt=0.0, le=1000.0, description="Position error of a done step at most, mm."
    )
    angle_tolerance: float = Field(
        3.0, gt=0.0, le=180.0, description="Angle error of a done step at most, degrees."
    )
    slip_tolerance: float = Field(
        5.0, gt=0.0, le=1000.0, description="Slip in the hand during the carry at most, mm."
    )
    drop_distance: float = Field(
        30.0,
        gt=0.0,
        le=10_000.0,
        description="Slip beyond which (or losing both fingers) the part counts as dropped, mm.",
    )
    stiffness: float = Field(
        3000.0, gt=0.0, le=1e6, description="Arm servo stiffness, N·m/rad (per joint)."
    )
    damping: float = Field(
        150.0,
        ge=0.0,
        le=1e5,
        description="Arm servo damping on the velocity error (velocity feed-forward), N·m·s/rad.",
    )
    decomposition_threshold: float = Field(
        0.02,
        gt=0.0,
        le=1.0,
        description="CoACD concavity threshold (smaller: more, tighter pieces).",
    )
    cache: str = Field(
        "",
        description="Folder caching convex decompositions by mesh content (default: "
        "$XDG_CACHE_HOME/thirdhand/coacd or ~/.cache/thirdhand/coacd).",
    )
    rate: float = Field(
        100.0, gt=0.0, le=10_000.0, description="Samples per second of the planned motion, Hz."
    )
    fps: int = Field(25, ge=1, le=120, description="Video frames per second.")
    width: int = Field(640, ge=64, le=4096, description="Video width, pixels.")
    height: int = Field(480, ge=64, le=4096, description="Video height, pixels.")
    meshes: list[str] = Field(
        default_factory=list,
        description="Folders searched for part meshes the task file does not find.",
    )
