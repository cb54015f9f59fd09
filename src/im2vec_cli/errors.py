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
