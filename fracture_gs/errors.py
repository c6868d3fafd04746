"""The exceptions a user of fracture-gs can meet, under one base class.

Each message is one sentence that names the file (or flag, or field), the value and the fix
(DESIGN.md "Errors"). The CLI prints it as one line with a non-zero exit; the Python API raises
it. Every class also derives from the builtin it refines, so `except ValueError` keeps working.
"""

from __future__ import annotations


class FractureGSError(Exception):
    """Base of every error fracture-gs raises on purpose."""


class ConfigError(FractureGSError, ValueError):
    """A config problem: `<file>: <field> <problem>; <fix>.`"""

    def __init__(self, source: str, field: str | None, message: str):
        self.source = source
        self.field = field
        super().__init__(f"{source}: {message}" if source else message)


class PlyError(FractureGSError, ValueError):
    """A PLY file that is not a readable 3DGS scene."""


class SceneError(FractureGSError, ValueError):
    """A scene that cannot be simulated as given (empty after cropping, all floaters, no fill)."""


class SimulationError(FractureGSError, ValueError):
    """Invalid simulation input (one sentence naming the field and the fix)."""


class SimulationDiverged(FractureGSError, RuntimeError):
    """The state became non-finite or exploded; carries the frame and the likely cause."""

    def __init__(self, message: str, frame: int, count: int, cause: str = ""):
        super().__init__(message)
        self.frame = frame
        self.count = count
        self.cause = cause


class OutputError(FractureGSError, OSError):
    """An output folder or file that cannot be written (a file in the way, no permission)."""


class RenderError(FractureGSError, ValueError):
    """A render setting that cannot be honoured (unknown mode or backend, a camera that sees nothing)."""


class ArgumentError(FractureGSError, TypeError, ValueError):
    """A Python API argument of the wrong type, shape or value: `<function>: <argument> <problem>; <fix>.`
    Both a TypeError and a ValueError, so code that caught what torch or os raised before keeps working."""


class ViewError(FractureGSError, ValueError):
    """A run folder `fracture-gs view` cannot show (no viewable frames, another version's record, a damaged
    file), or a viewer that cannot start (the port is taken, viser missing)."""
