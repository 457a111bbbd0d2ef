"""Settings of ``thirdhand live`` (``[live]`` of ``--config``).

The segmentation model and the robot assist's knobs; the defaults are those the
live loop's figures are measured with (``docs/explanation/live.md``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pydantic import Field

from thirdhand.settings import Settings

if TYPE_CHECKING:
    from thirdhand.live.assist import AssistOptions


class LiveSettings(Settings):
    """The live loop's model and the simulated assist's arm, base and timing."""

    segment_model: str | None = Field(
        None,
        description="Segmentation model JSON (e.g. from `segment calibrate`) or built-in "
        "name (default: the shipped model).",
    )
    robot: str = Field("panda", description="The assist's arm (--assist).")
    handover_m: tuple[float, float, float] = Field(
        (0.07, 0.0, 0.35),
        description="Hand-over point from the assembly's root towards the robot, metres.",
    )
    joint_speed: float = Field(1.5, gt=0, le=10, description="Arm joint speed, rad/s.")
    grasp_s: float = Field(0.5, ge=0, le=10, description="Time to close the gripper, s.")
    lift_m: float = Field(0.06, ge=0, le=0.5, description="Lift off the table, metres.")
    plan_time_s: float = Field(
        1.0, gt=0, le=60, description="Time limit of each planning query, s."
    )
    wait_for_person: bool = Field(
        True, description="Fetch nothing until the person has a part in hand or a step is done."
    )
    base_track_m: float = Field(
        1.2,
        ge=0,
        le=10,
        description="Length of the base's track across the assembly's far side, metres "
        "(0: a fixed base).",
    )
    base_speed: float = Field(0.5, gt=0, le=5, description="Speed of the base, m/s.")
    follow_idle_s: float = Field(
        10.0,
        gt=0,
        le=3600,
        description="An MCAP being written ends after this many seconds without a new byte.",
    )

    def assist_options(self) -> AssistOptions:
        """The assist's options these settings give."""
        from thirdhand.live.assist import AssistOptions

        return AssistOptions(
            robot=self.robot,
            handover_m=self.handover_m,
            joint_speed=self.joint_speed,
            grasp_s=self.grasp_s,
            lift_m=self.lift_m,
            plan_time_s=self.plan_time_s,
            wait_for_person=self.wait_for_person,
            base_track_m=self.base_track_m,
            base_speed=self.base_speed,
        )
