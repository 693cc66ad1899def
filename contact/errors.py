"""Exceptions raised by :mod:`contact`."""

from __future__ import annotations

__all__ = [
    "BallError",
    "ContactError",
    "InputError",
    "ObjectError",
    "OutputError",
    "PoseError",
    "RigError",
    "SceneError",
    "SurfaceError",
    "TargetError",
]


class ContactError(Exception):
    """Base class of every error raised by :mod:`contact`."""


class RigError(ContactError, ValueError):
    """A hand rig is invalid (file, key, value), or a pose asks for what the rig forbids.

    The message is one line that names the file and key path, or the joint, at fault.
    """


class PoseError(RigError):
    """A pose the flesh mesh cannot take: the mapping inverts an element.

    Attributes
    ----------
    joint : str
        The joint whose motion inverted it (the most bent joint acting on its nodes).
    element : int
        Index of the first inverted tetrahedron.
    elements : tuple of int
        Every inverted tetrahedron.
    """

    def __init__(self, message: str, joint: str, element: int, elements: tuple[int, ...]):
        super().__init__(message)
        self.joint = joint
        self.element = element
        self.elements = elements


class SceneError(ContactError, ValueError):
    """A scene file is invalid: one line ``<file>: <key.path> = <value>: <what is wrong>``."""


class InputError(ContactError, ValueError):
    """Bad input found while setting a frame up (exit status 2)."""


class BallError(ContactError, ValueError):
    """A ball specification or mesh file is invalid; one line naming the field or file."""


class ObjectError(ContactError, ValueError):
    """An object's specification or mesh file is invalid; one line naming the key or file."""


class SurfaceError(ContactError, ValueError):
    """A triangle surface or a query is invalid; one line that names the surface."""


class OutputError(ContactError, OSError):
    """The results folder cannot be written (the message names the folder)."""


class TargetError(OutputError):
    """The results folder asked for may not be replaced (foreign files, not a folder).

    Bad input (exit status 2), unlike the other :class:`OutputError` (an I/O failure).
    """
