"""The exceptions freeform raises, by kind. Every one carries the library's message."""


class FreeformError(Exception):
    """Base class of every error freeform raises."""


class InvalidInputError(FreeformError, ValueError):
    """A parameter, array, shape or scene is invalid: the message says which and why."""


class CoverageError(InvalidInputError):
    """Points are not covered by enough RKPM kernels (raise ``support_factor`` or
    ``kernels``, or check for isolated points)."""


class NotConvergedError(FreeformError, RuntimeError):
    """The eigensolver (or the FEM reference) did not converge or broke down."""


class StrictModeError(FreeformError, RuntimeError):
    """``strict=True`` was asked for and a warning was raised (``.args[0]`` lists it)."""


class FreeformIOError(FreeformError, OSError):
    """A file could not be read or written, or is not a valid freeform file."""
