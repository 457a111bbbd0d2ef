"""Synthetic assembly demonstrations with exact ground truth.

``make_scene(name, seed=..., sensor=SensorModel(), n_people=1, **options)`` returns a
:class:`thirdhand.Demonstration` of a person (or two) assembling a ``chair``, a
``bench``, a ``toolbox``, or mounting a ``drawer`` (prismatic) or a ``lid``
(revolute), with the interactions, constraints and plan in ``demo.labels``.

Interaction follows the 3rdHand report's definition: two bodies interact while
they move together under a (temporarily) rigid transformation. Ground truth,
exactly as simulated (see :mod:`thirdhand.synth.script`):

- finger–part (and finger–tool) interactions, direct: from the instant the
  fingers close on the object to the instant they start opening; in between,
  each fingertip's pose in the object's frame is constant.
- finger–part interactions through a held part (the transitive rule): a finger
  holding ``Q`` also interacts with every body ``P`` that interacts with ``Q``
  (part–part or tool–part, below) while ``P``'s pose in ``Q`` stays constant. A
  finger holding the seat interacts with the legs already screwed in and with
  the leg being screwed in while it rests in its thread between two strokes,
  not while it turns, nor with a drawer sliding in a frame it holds. Hands
  (fingers grouped by ``hand_body``) follow their fingers.
- tool–part interactions: the screwdriver and the screw it drives, from
  engagement to disengagement (the screwdriver's pose in the screw is constant;
  the hand releases and regrips the handle between strokes meanwhile); through
  the links below, also the parts that screw rests in between strokes (the
  board, and what the board is joined to).
- part–part interactions follow the same definition, applied to the joints: two
  parts interact while a chain of *links* connects them, each link at rest in
  its joint (the child's pose in the parent constant; rigidity is checked on a
  960 Hz grid). A link is a constraint from the moment it is established to the
  end of the recording (or its removal), or a part seated in its joint before
  that: a leg from its insertion into the thread (between screwing strokes it
  rests there and moves with the seat), a screw resting in its hole. While a
  leg or screw turns, a drawer slides in its rails or a lid turns on its hinges,
  its link is broken, so a leg being screwed in interacts with the seat only in
  the pauses between strokes, exactly like a drawer between two pushes; fixed
  joints and tight legs are rigid throughout. A constraint is established at the
  first instant from which the child's pose in the parent stays within the
  constraint for good: a chair leg when its last screwing turn ends, a screw
  when it is tight, a toolbox board when its last screw is tight, the back when
  it is pushed home, a drawer when it enters its rails, a lid when it is on its
  hinge pins. For fixed constraints the relative pose is then constant; for the
  drawer and the lid it moves only along the free DOF.
- the human: a held part resting in the world (and everything attached to it)
  follows the holding hand's low-frequency motion (a few millimetres and a
  degree or two at 0.3–3 Hz, plus a push and twist during each screwing stroke
  or slide of the other hand; :class:`thirdhand.synth.motion.Wobble`); when
  released it stays where the hand left it. Idle hands sway on their own (a few
  millimetres, about two degrees). The fingers' pose in a held part is still
  exactly constant, and constraint poses are the child's actual pose in the parent.
- constraints: ``pos``/``quat`` are the child's pose in the parent at the joint's
  reference: the pose at the moment it is established for fixed constraints and
  legs (equal to the final pose), the closed position for the drawer and the lid
  (also their final pose). Free DOFs are expressed in that frame: a leg spins
  freely about its own ``x`` axis (``rx ∈ [−π, π]``), the drawer slides along
  ``tx ∈ [0, travel]``, the lid opens about ``rx ∈ [0, 110°]``.
- plan: one step per constraint, in time order, symbols named by slot (``c1``…
  by position on the base, ``s1``… by screw hole) whichever part goes there.
"""

from thirdhand.synth.build import SCENES, make_scene, random_scene
from thirdhand.synth.geometry import PartGeometry, read_stl, stl_bounds
from thirdhand.synth.human import HumanModel
from thirdhand.synth.motion import min_jerk
from thirdhand.synth.sensor import SensorModel

__all__ = [
    "SCENES",
    "HumanModel",
    "PartGeometry",
    "SensorModel",
    "make_scene",
    "min_jerk",
    "random_scene",
    "read_stl",
    "stl_bounds",
]
