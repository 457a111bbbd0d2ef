"""Review and correction of a learned task: the model layer under the review GUI.

Everything here is plain functions and small classes on the task model
(:class:`thirdhand.taskfile.TaskFile`), tested without a browser; the viser GUI
(``thirdhand.review.app``) is a thin layer of handles and callbacks over them.

- :mod:`~thirdhand.review.edits`: the corrections, ``apply_edit(task, edit) -> task``.
- :mod:`~thirdhand.review.history`: undo and redo.
- :mod:`~thirdhand.review.effort`: GUI operations per object, changed parameters.
- :mod:`~thirdhand.review.session`: a task file under review, saved safely.
- :mod:`~thirdhand.review.clarify`: questions ordered by the system's uncertainty.
- :mod:`~thirdhand.review.dofs`: world poses, DOF animations and classes.
- :mod:`~thirdhand.review.transfer`: a task mapped onto another object set.
- :mod:`~thirdhand.review.view`: what is shown (selection, keyframe, chosen step).
- :mod:`~thirdhand.review.corrections`: the widgets' input as edits.
- :mod:`~thirdhand.review.rounds`: the clarification and phase-labelling rounds.
- :mod:`~thirdhand.review.dialogs`: what is asked and told, and when.
- :mod:`~thirdhand.review.panel_html`: the panel's HTML.

The GUI's shells keep only handles, threads and caches: the app
(``review.app``), its panel (``review.panels``), its 3D view
(``review.task_scene``), its tabs (``review.tabs``), its playback
(``review.motion``) and its question rounds (``review.questioning``).
"""

from thirdhand.review.clarify import Question, clarification_queue
from thirdhand.review.dofs import classify_dof, dof_animation, world_poses
from thirdhand.review.edits import (
    Confirm,
    Edit,
    EditError,
    MoveStep,
    SetDofRange,
    SetParent,
    SetPose,
    SetPoseValue,
    SetPrimitivePoint,
    apply_correction,
    apply_edit,
    parse_number,
)
from thirdhand.review.effort import OPERATIONS, EffortLog, changed_parameters
from thirdhand.review.history import History
from thirdhand.review.session import ConflictError, ReviewSession
from thirdhand.review.transfer import TransferError, TransferResult, transfer, transfer_task

__all__ = [
    "OPERATIONS",
    "Confirm",
    "ConflictError",
    "Edit",
    "EditError",
    "EffortLog",
    "History",
    "MoveStep",
    "Question",
    "ReviewSession",
    "SetDofRange",
    "SetParent",
    "SetPose",
    "SetPoseValue",
    "SetPrimitivePoint",
    "TransferError",
    "TransferResult",
    "apply_correction",
    "apply_edit",
    "changed_parameters",
    "clarification_queue",
    "classify_dof",
    "dof_animation",
    "parse_number",
    "transfer",
    "transfer_task",
    "world_poses",
]
