"""Physics simulation of a planned run (MuJoCo): does each step work with contacts?

Imported only by ``thirdhand simulate`` (the ``sim`` extra: mujoco, coacd). The modules:
:mod:`~thirdhand.simulate.settings` (the settings record),
:mod:`~thirdhand.simulate.plan` (the run to replay: planned now or recorded),
:mod:`~thirdhand.simulate.parts` (collision pieces, mass from volume, the decomposition
cache), :mod:`~thirdhand.simulate.cell` and :mod:`~thirdhand.simulate.model` (the MuJoCo
model), :mod:`~thirdhand.simulate.schedule` (phases: move, close, fasten, open, rest),
:mod:`~thirdhand.simulate.runner` (stepping and measuring),
:mod:`~thirdhand.simulate.measure` (pose error, slip, status: pure functions),
:mod:`~thirdhand.simulate.run` (one run end to end), :mod:`~thirdhand.simulate.report`
(the JSON document), :mod:`~thirdhand.simulate.video` (offscreen MP4) and
:mod:`~thirdhand.simulate.cli` (the command).
"""
