"""The layout's promises (docs/architecture.md): what dances loads no training, data, evaluation or command code;
`dancenet --help` is quick and torch-free; the command line and the settings dataclasses agree; and the
import contracts hold."""

from __future__ import annotations

import ast
import json
import shutil
import subprocess
import sys
import time
from dataclasses import fields
from pathlib import Path

import pytest

from dancenet_core import __version__
from dancenet_core.cli import build_parser
from dancenet_core.training.configs import FootfixSettings, MotionStyleSettings, StyleSettings, TrainSettings, from_args

REPO = Path(__file__).resolve().parents[1]
APART_FROM_DANCING = ("dancenet_core.data", "dancenet_core.training", "dancenet_core.evaluation",
                      "dancenet_core.commands", "matplotlib", "sklearn")


def _modules_after(code: str) -> list[str]:
    """The modules loaded by `code` in a fresh interpreter."""
    probe = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True, cwd=REPO)
    return json.loads(out.stdout.splitlines()[-1])


@pytest.mark.parametrize("prefix", APART_FROM_DANCING)
def test_importing_generate_loads_nothing_apart_from_dancing(prefix: str) -> None:
    loaded = _modules_after("import dancenet_core.generate")
    assert [m for m in loaded if m == prefix or m.startswith(prefix + ".")] == []


def test_the_shared_defaults_load_no_library() -> None:
    """The add-on reads the generation defaults when it registers, where loading the generator would cost a
    second: `dancenet_core.constants` loads neither numpy nor anything above it."""
    loaded = _modules_after("import dancenet_core.constants")
    assert [m for m in loaded if m.split(".")[0] in ("numpy", "scipy", "numba", "torch")] == []


def test_help_does_not_import_torch() -> None:
    loaded = _modules_after("import contextlib\nfrom dancenet_core.cli import main\n"
                            "with contextlib.suppress(SystemExit):\n    main(['--help'])")
    assert "torch" not in loaded


def test_help_takes_under_half_a_second() -> None:
    """Best of three runs of the installed command (the machine is shared)."""
    dancenet = shutil.which("dancenet", path=str(Path(sys.executable).parent))
    assert dancenet is not None
    times = []
    for _ in range(3):
        t = time.perf_counter()
        subprocess.run([dancenet, "--help"], capture_output=True, check=True)
        times.append(time.perf_counter() - t)
    assert min(times) < 0.5


def test_version() -> None:
    out = subprocess.run([sys.executable, "-m", "dancenet_core.cli", "--version"], capture_output=True, text=True,
                         cwd=REPO)
    assert out.stdout.strip() == f"dancenet {__version__}"


@pytest.mark.parametrize(("model", "settings"), [("dancenet", TrainSettings), ("footfix", FootfixSettings),
                                                 ("style", StyleSettings), ("motion-style", MotionStyleSettings)])
def test_train_options_are_the_settings_dataclass(model: str, settings: type) -> None:
    """Every field is an option, and with no options the command trains with the dataclass's defaults."""
    args = build_parser(["train", model]).parse_args(["train", model])
    assert from_args(settings, args) == settings()
    assert {f.name for f in fields(settings)} <= set(vars(args))


def test_train_options_set_the_settings() -> None:
    argv = ["train", "dancenet", "--steps", "7", "--residual-output", "--init", "a.pt", "--out", "runs/x"]
    got = from_args(TrainSettings, build_parser(argv).parse_args(argv))
    assert got == TrainSettings(steps=7, residual_output=True, init=Path("a.pt"), out=Path("runs/x"))


def test_import_contracts_hold() -> None:
    """import-linter's contracts in pyproject.toml (layers; what dances imports; no cycles)."""
    lint = Path(sys.executable).parent / "lint-imports"
    out = subprocess.run([str(lint), "--no-cache"], capture_output=True, text=True, cwd=REPO)
    assert out.returncode == 0, out.stdout[-3000:]


LONGEST_FUNCTION = 80  # lines
MOST_PARAMETERS = 12


def _functions(package: str) -> list[tuple[str, int, int]]:
    """(where, lines, parameters) of every function and method in `package`, nested ones included."""
    out = []
    for path in sorted((REPO / package).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                a = node.args
                count = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + (a.vararg is not None) + (
                    a.kwarg is not None)
                out.append((f"{path.relative_to(REPO)}:{node.lineno} {node.name}", node.end_lineno - node.lineno + 1,
                            count))
    return out


@pytest.mark.parametrize("package", ["dancenet_core", "blender_addon"])
def test_no_function_is_long_or_takes_many_parameters(package: str) -> None:
    """A function a reader takes in at once: at most 80 lines and 12 parameters (a numba kernel takes its arrays
    as one typed bundle, runtime.sampler.Arrays)."""
    found = _functions(package)
    assert found
    assert [(f, n) for f, n, _p in found if n > LONGEST_FUNCTION] == []
    assert [(f, p) for f, _n, p in found if p > MOST_PARAMETERS] == []


def _imports(package: str) -> dict[str, set[str]]:
    """Each module of `package` and the modules of it that it imports, at its top or inside a function."""
    modules = {}
    for path in sorted((REPO / package).rglob("*.py")):
        parts = path.relative_to(REPO).with_suffix("").parts
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        here = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = here.split(".")[: len(here.split(".")) - node.level + 1]
                    base = ".".join([*anchor, base] if base else anchor)
                targets |= {f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names}
            elif isinstance(node, ast.Import):
                targets |= {a.name for a in node.names}
        # a package's own __init__ runs first anyway: importing it from inside is no circle
        graph[name] = {t for t in targets if t in modules and t != name and not name.startswith(t + ".")}
    return graph


def test_the_core_loads_no_module_by_file() -> None:
    """import-linter's contract "The core never imports the add-on" sees import statements only: a module loaded
    from its file (importlib's spec_from_file_location, runpy) would pass it, so the core does neither (it runs
    the add-on's FBX writer as a script in a child process)."""
    found = []
    for path in sorted((REPO / "dancenet_core").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            name = node.attr if isinstance(node, ast.Attribute) else node.id if isinstance(node, ast.Name) else None
            if name in ("spec_from_file_location", "SourceFileLoader", "run_path", "exec_module"):
                found.append(f"{path.relative_to(REPO)}:{node.lineno} {name}")
    assert found == []


@pytest.mark.parametrize("package", ["dancenet_core", "blender_addon"])
def test_no_import_circle(package: str) -> None:
    """No module imports, at its top or late inside a function, a module that imports it back (directly or
    round a longer circle): each can be read, and changed, knowing only what lies below it."""
    graph, circles, state = _imports(package), [], {}

    def visit(module: str, path: list[str]) -> None:
        state[module] = "open"
        for target in sorted(graph[module]):
            if state.get(target) == "open":
                circles.append([*path[path.index(target):], target])
            elif target not in state:
                visit(target, [*path, target])
        state[module] = "done"

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    assert circles == []
