"""What holds an object: force-driven fingers (:mod:`.fingerforce`), the least grip.

The least grip is :mod:`.leastgrip`. Nothing is re-exported here: :mod:`contact.run`
uses the fingers' force search, and the least grip runs :class:`contact.run.GraspRun`.
"""

from __future__ import annotations

__all__: list[str] = []
