"""Former name of the generator with RCCL's adaptive features (thesis 5.4, 5.6.1): now every generator has them.

Functional transforms limited per sample (E.8), conditional motions (5.6.1) and the
Figure 5.4 exit from a modified segment are part of ``rccl.trajectory.TrajectoryGenerator``
itself (and the functional transforms and conditional motions of ``rccl.jerk``'s); the
motion checks of the next motion wait in ``MotionQueue.pending``. These names stay for
programs written against them.
"""
from __future__ import annotations

from ..queue import MotionQueue as HookQueue
from ..trajectory import TrajectoryGenerator as AdaptiveGenerator

__all__ = ["AdaptiveGenerator", "HookQueue"]
