"""Exceptions raised by the library. The CLI turns them into one-line errors."""


class Im2VecError(Exception):
    """Base class for every error a user can cause (bad input, bad model, bad option)."""


class InputError(Im2VecError):
    """An input file is missing, unreadable or not an image."""


class ModelError(Im2VecError):
    """A model name or directory cannot be resolved or loaded."""


class DataError(Im2VecError):
    """A dataset folder is empty, malformed, or a source package is missing."""


class TrainingError(Im2VecError):
    """Training cannot go on (e.g. the loss stays non-finite)."""


class ConfigError(Im2VecError, ValueError):
    """A configuration value no model or run can use (also a ``ValueError``, for programmers)."""


class TraceError(Im2VecError):
    """A picture is beyond what tracing can bound (too many regions, too fragmented)."""


class VectorizeError(Im2VecError):
    """One picture's pipeline failed (any exception inside it); the others of its batch go on."""


class OptionWarning(UserWarning):
    """An option was set that does nothing in the mode chosen (``VectorizeOptions.idle``)."""


def describe(exc: BaseException) -> str:
    """One line for an exception the library did not raise on purpose (a dependency's error,
    memory running out): its own message for an ``Im2VecError``, else what happened and the
    exception's type, without a traceback."""
    if isinstance(exc, Im2VecError):
        return str(exc)
    if isinstance(exc, MemoryError) or "can't allocate memory" in str(exc) or "out of memory" in str(exc).lower():
        return "out of memory (" + (str(exc).splitlines() or ["MemoryError"])[0][:200] + ")"
    text = (str(exc).splitlines() or [""])[0][:200]
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__
