"""The 3D view of an arm in a web browser (viser): the scene, the process that serves it, a
recorded run replayed, screenshots, and an RCCL program's live plan.

* ``rcci.view.scene.ArmView``: the arm from its URDF, the environment's surfaces, paths, a
  target frame and a status line, served by viser;
* ``rcci.view.process``: the view's own process (``python -m rcci.view.process``), fed JSON
  lines by ``rci.view_link.ViewFeed``, so the viewed process never waits on the drawing;
* ``rcci.view.replay``: a recorded ``.rcilog`` replayed (``python -m rcci.view.replay LOG``);
* ``rcci.view.plan.show(arm)``: an RCCL program's arm, planned paths and target, live;
* ``rcci.view.screenshot``: a picture of a view through a headless Chromium (tests, docs).

The view sits on the top floor: it reads rci and rccl and nothing below imports it. What a
viewed process needs to feed it is ``rci.view_link`` (simula's ``--view`` uses that alone).
The extra ``view`` installs viser (``pip install '.[view]'``); docs/viewer.md shows it.
"""
