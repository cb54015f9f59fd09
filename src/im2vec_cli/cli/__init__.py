"""The ``im2vec`` command line: a thin layer over the Python API (``api.py``) and the pipelines.

The only package that prints, reads argv or exits. Subcommands import torch and the library
inside their bodies, so ``im2vec --help`` stays fast. One module per command family
(``convert``, ``generate``, ``training``, ``evaluation``, ``datasets``); ``app`` holds the
group and the error mapping, ``streams`` stdin/stdout and atomic writes, ``batch`` the batch
runner and its ``Report``, ``options`` the shared options.

Exit codes: 0 success; 1 an error (bad input, bad model, failed write; some files of a
batch failed); 2 bad usage; 130 interrupted (Ctrl-C); 143 terminated (SIGTERM).
"""

from . import convert, generate  # noqa: F401 - they register their commands; app.LAZY's register when asked for
from .app import EXIT_HELP, cli
from .convert import encode, render, vectorize
from .generate import interpolate, sample

__all__ = ["EXIT_HELP", "cli", "encode", "interpolate", "main", "render", "sample", "vectorize"]


def main():
    cli(prog_name="im2vec")
