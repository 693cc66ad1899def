"""Exceptions raised by :mod:`contact`."""

from __future__ import annotations

__all__ = ["ContactError", "RigError"]


class ContactError(Exception):
    """Base class of every error raised by :mod:`contact`."""


class RigError(ContactError, ValueError):
    """A hand rig is invalid (file, key, value), or a pose asks for what the rig forbids.

    The message is one line that names the file and key path, or the joint, at fault.
    """
