"""A scene's run, frame by frame: the bodies that last, and how a frame is stepped.

:class:`GraspRun` (:mod:`contact.run.grasprun`) sets a scene up and solves its frames;
:mod:`contact.run.stepping` steps a frame in time (friction's substeps, a finite frame's
cut-backs); :mod:`contact.run.rolling` places a rolled linear ball anew.
"""

from .grasprun import GraspRun

__all__ = ["GraspRun"]
