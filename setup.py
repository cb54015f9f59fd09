"""The wheel carries the shipped models inside the package (``im2vec_cli/models/NAME``, where
``config.PACKAGE_MODELS`` looks), so that ``pip install .`` (not editable) works from
any folder with the default model. Everything else is in pyproject.toml."""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

SHIPPED_MODELS = ("fonts", "mnist", "emoji", "icons")  # the models the commands name; models/ holds research too


class BuildWithModels(build_py):
    """``build_py`` that also copies ``models/NAME`` for each shipped model into the built package
    (an editable install finds them in the repository instead)."""

    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return
        here = Path(__file__).resolve().parent / "models"
        for name in SHIPPED_MODELS:
            if not (here / name / "config.json").is_file():
                raise FileNotFoundError(f"models/{name}/config.json: the wheel would ship without its model")
            shutil.copytree(here / name, Path(self.build_lib) / "im2vec_cli" / "models" / name, dirs_exist_ok=True)


setup(cmdclass={"build_py": BuildWithModels})
