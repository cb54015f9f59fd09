"""The layout rules of shared/STYLE.md, checked from the source so that they stay true.

- Imports flow down the layers: cli -> api -> pipelines -> model | data -> trace -> vector -> raster
  -> ground floor. Imports inside functions count too.
- ``model/`` never imports ``data/`` and ``data/`` never imports ``model/``.
- ``cli/`` imports only ``api``, ``options`` and the ground floor: api.py is its one door.
- Nothing imports a private (``_x``) module or name of another package.
- Library code (everything but ``cli/``) never imports click and never calls ``sys.exit``.
- No function is longer than ``MAX_LINES``, except those listed in ``LONG`` with the reason.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "im2vec_cli"
PKG = "im2vec_cli"

LAYERS = {  # first component under im2vec_cli -> layer; higher may import lower or equal
    "errors": 0, "config": 0, "files": 0, "runtime": 0, "frame": 0, "optim": 0, "checkpoint": 0, "options": 0, "events": 0,
    "lazy": 0,
    "raster": 1,
    "vector": 2,
    "trace": 3,
    "model": 4, "data": 4,
    "infer": 5, "project": 5, "refine": 5, "training": 5, "evaluate": 5,
    "api": 6, "extras": 6, "parallel": 6, "rayengine": 6, "vectorizing": 6, "report": 6,
    "cli": 7, "__main__": 7,
}
SIBLINGS_APART = {("model", "data"), ("data", "model")}
CLI_MAY = {"cli", "api", "options"}  # and the ground floor (layer 0): the CLI parses, api.py does the work
MAX_LINES = 60
MAX_MODULE_LINES = 400
LONG: dict[str, str] = {}  # function -> why it stays long (none now)


def modules() -> list[tuple[Path, str]]:
    """Every source file and its dotted module name."""
    out = []
    for f in sorted(SRC.rglob("*.py")):
        rel = f.relative_to(SRC).with_suffix("")
        parts = [p for p in rel.parts if p != "__init__"]
        out.append((f, ".".join([PKG, *parts])))
    return out


def imports(path: Path, module: str) -> list[tuple[str, list[str], int]]:
    """``(imported module, imported names, line)`` for every im2vec import of a file."""
    is_pkg = path.name == "__init__.py"
    package = module if is_pkg else module.rsplit(".", 1)[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(a.name, [], node.lineno) for a in node.names if a.name.split(".")[0] == PKG]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != PKG:
                continue
            names = [a.name for a in node.names]
            # `from . import x` imports the module x when x is one
            subs = [n for n in names if (SRC / Path(*target.split(".")[1:]) / n).with_suffix(".py").exists()
                    or (SRC / Path(*target.split(".")[1:]) / n).is_dir()]
            out += [(f"{target}.{n}", [], node.lineno) for n in subs]
            rest = [n for n in names if n not in subs]
            if rest or not subs:
                out.append((target, rest, node.lineno))
    return out


def top(module: str) -> str | None:
    """The first component under the package (``None`` for the package root)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def violations() -> list[str]:
    bad = []
    for path, mod in modules():
        src = top(mod)
        if src is None:  # the package root: __version__ and the lazy API re-exports
            continue
        for target, names, line in imports(path, mod):
            dst = top(target)
            where = f"{path.relative_to(SRC)}:{line}"
            if dst is None:
                if set(names) - {"__version__"}:
                    bad.append(f"{where}: imports {names} from the package root")
                continue
            if dst not in LAYERS or src not in LAYERS:
                bad.append(f"{where}: {target} has no layer in LAYERS")
            elif LAYERS[dst] > LAYERS[src]:
                bad.append(f"{where}: {src} (layer {LAYERS[src]}) imports {target} (layer {LAYERS[dst]})")
            if (src, dst) in SIBLINGS_APART:
                bad.append(f"{where}: {src}/ imports {target}")
            if src == "cli" and dst not in CLI_MAY and LAYERS.get(dst) != 0:
                bad.append(f"{where}: the CLI imports {target} (it goes through api.py)")
            own_package = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]
            tail = target.split(".")
            private_mod = any(p.startswith("_") and not p.startswith("__") for p in tail)
            outside = not (target.startswith(own_package + ".") or target == own_package)
            if outside and (private_mod or any(n.startswith("_") and not n.startswith("__") for n in names)):
                bad.append(f"{where}: private import {target} {names}")
    return bad


def test_imports_follow_the_layers():
    assert violations() == []


def test_the_checker_catches_an_upward_and_a_private_import(tmp_path, monkeypatch):
    """The rules can fail: a raster module that imports the model, and a cli module that
    imports raster._compile, are both reported."""
    fake = tmp_path / "im2vec_cli"
    (fake / "raster").mkdir(parents=True)
    (fake / "cli").mkdir()
    (fake / "raster" / "bad.py").write_text("from ..model import build_model\n")
    (fake / "raster" / "_compile.py").write_text("")
    (fake / "cli" / "bad.py").write_text("from ..raster._compile import set_compile\n")
    (fake / "model").mkdir()
    (fake / "model" / "bad.py").write_text("def f():\n    from ..data.folder import list_images\n")
    monkeypatch.setattr(__import__(__name__, fromlist=["SRC"]), "SRC", fake)
    found = "\n".join(violations())
    assert "raster (layer 1) imports im2vec_cli.model (layer 4)" in found
    assert "private import im2vec_cli.raster._compile" in found
    assert "model/ imports im2vec_cli.data.folder" in found
    assert "cli/bad.py:1: the CLI imports im2vec_cli.raster._compile (it goes through api.py)" in found


def test_library_code_never_uses_click_or_exits():
    bad = []
    for path, mod in modules():
        if top(mod) in ("cli", "__main__"):
            continue
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in node.names] + ([node.module] if isinstance(node, ast.ImportFrom) else [])
                if any(n and n.split(".")[0] == "click" for n in names):
                    bad.append(f"{path.relative_to(SRC)}:{node.lineno}: imports click")
            if isinstance(node, ast.Attribute) and node.attr == "exit" and getattr(node.value, "id", "") == "sys":
                bad.append(f"{path.relative_to(SRC)}:{node.lineno}: sys.exit")
    assert bad == []


def scripts() -> list[Path]:
    """The benchmarks' and the docs' scripts (bench/, bench/research/, docs/), held to the same lengths."""
    root = SRC.parents[1]
    return sorted([*root.glob("bench/*.py"), *root.glob("bench/research/*.py"), *root.glob("docs/*.py")])


def _shown(path: Path) -> str:
    return str(path.relative_to(SRC if SRC in path.parents else SRC.parents[1]))


@pytest.mark.parametrize("path", [p for p, _ in modules()] + scripts(), ids=_shown)
def test_functions_are_short(path):
    long = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            key = f"{_shown(path)}:{node.name}"
            if node.end_lineno - node.lineno + 1 > MAX_LINES and key not in LONG:
                long.append(f"{key} ({node.end_lineno - node.lineno + 1} lines)")
    assert long == []


@pytest.mark.parametrize("path", [p for p, _ in modules()] + scripts(), ids=_shown)
def test_modules_are_short(path):
    """A module is one idea: at most MAX_MODULE_LINES lines (split it into a package when it grows)."""
    assert len(path.read_text().splitlines()) <= MAX_MODULE_LINES


def test_readme_is_short_and_every_link_in_the_docs_resolves():
    """README stays a front page (what it is, the two commands, the commands, the API, the
    models, links), and a moved section never leaves a dead relative link behind."""
    import re

    root = SRC.parents[1]
    readme = root / "README.md"
    lines = readme.read_text().splitlines()
    assert len(lines) <= 200
    head = "\n".join(lines[:12])  # what it is, then the two commands, before anything else
    assert "SVG" in head and "potrace" in head and "vtracer" in head
    assert head.index("SVG") < head.index("make demo") < head.index("make test")
    dead = []
    for doc in [readme, *sorted((root / "docs").glob("*.md"))]:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", doc.read_text()):
            if "://" not in target and not (doc.parent / target).exists():
                dead.append(f"{doc.relative_to(root)} -> {target}")
    assert dead == []


def test_the_architecture_doc_draws_the_layers_the_code_has():
    """docs/ARCHITECTURE.md's layer table is ``LAYERS``, and ``LAYERS`` names every module and package
    at the package root: a module added, moved or re-layered without redrawing the doc fails here."""
    import re

    doc = (SRC.parents[1] / "docs" / "ARCHITECTURE.md").read_text()
    table = doc.split("<!-- layers:begin -->", 1)[1].split("<!-- layers:end -->", 1)[0]
    drawn = {name: int(layer) for layer, names in re.findall(r"^\| (\d+) \| (.+) \|$", table, re.M)
             for name in re.findall(r"`([\w]+)`", names)}
    assert drawn == LAYERS
    roots = {p.stem if p.is_file() else p.name for p in SRC.iterdir()
             if (p.suffix == ".py" and p.stem != "__init__") or (p.is_dir() and (p / "__init__.py").is_file())}
    assert roots == set(LAYERS)
