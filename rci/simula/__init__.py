"""simula: the RCI robot simulator (thesis A.7), a separate process speaking the RCI link protocol.

Modules: ``params`` (ground truth and disturbances), ``friction`` (eq. 4.27 and the
4.5.3-4.5.5 effects), ``arm`` (the simulated arm, pure), ``server`` (sessions over a
socket or pty, real-time and lockstep), ``control`` (the test control channel),
``process`` (start a simula process from Python), ``environment`` (contact surfaces and a
conveyor, for the RCCL adaptive-control examples), ``__main__`` (the console script).
See docs/simula.md.
"""
