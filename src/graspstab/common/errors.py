"""The base class of graspstab's own errors, and the disk-space error every stage may raise.

A :class:`GraspstabError` is a failure the user can fix, raised with a message that says what is
wrong and how to fix it. A workflow job that raises one ends with that message alone, without a
Python traceback (:func:`graspstab.common.jobs.job`); any other exception is a bug and keeps its
traceback. Each stage's error classes keep their historic built-in base (``ValueError``,
``RuntimeError``, ...) and add this one, so existing ``except`` clauses still catch them.
"""

from __future__ import annotations


class GraspstabError(Exception):
    """A failure with a message for the user (what is wrong, and the fix); no traceback needed."""


class DiskSpaceError(GraspstabError):
    """A filesystem has (or would have) too little free space for a job's outputs; the message
    names the paths, the free space and the fix."""
