"""Error types raised by qpik.

Every error that qpik raises on purpose derives from :class:`QpikError`.
Errors about a caller's input also derive from :class:`ValueError`, so that
``except ValueError`` keeps working for code that does not know qpik.
"""

from __future__ import annotations


class QpikError(Exception):
    """Base class of every error qpik raises on purpose."""


class InputError(QpikError, ValueError):
    """An argument has the wrong shape, holds NaN/inf, or is out of its domain."""


class RotationError(InputError):
    """A rotation matrix is not orthonormal (within 1e-6) and projection was not asked for."""


class UnknownRobotError(QpikError, KeyError):
    """``load_robot`` was given a name that is not in the catalog."""

    def __str__(self) -> str:  # KeyError quotes its message; keep it readable
        return str(self.args[0]) if self.args else ""


class NoClosedFormError(QpikError, TypeError):
    """The robot has no closed-form inverse kinematics (for example ``zheng7``, ``panda``)."""


class ProblemFileError(InputError):
    """A ``problems/*.toml`` file is missing a field, has a wrong shape or an unknown value."""


class UnreachableError(QpikError):
    """A target pose cannot be reached by any branch at any redundancy parameter."""


class InfeasibleError(QpikError):
    """A QP or NLP has no feasible point (for example conflicting limits)."""


class SolverError(QpikError):
    """A numerical solver failed or is not installed."""


class RenderUnavailable(QpikError):  # noqa: N818 (the name says what the caller catches)
    """No OpenGL context could be made for offscreen rendering (message: one line)."""


class ViewerError(QpikError):
    """The viewer cannot run: viser is not installed, the port is taken, or no headless browser for a picture."""
