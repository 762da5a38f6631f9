"""The floors of the package: each imports only the floors below it, and no module imports in a circle.

Every ``import`` and ``from ... import`` of every module counts, at module level or inside a
function, under ``TYPE_CHECKING`` or not: an import put off to run time still ties the floors.
The checks run on the source files (:mod:`ast`), nothing is imported.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "rkmpc"

#: The floors, lowest first; ``api`` is the package's ``__init__`` (the public names).
LAYERS = (
    "core",
    "track",
    "vehicle",
    "learning",
    "estimation",
    "control",
    "config",
    "sim",
    "envs",
    "analysis",
    "experiments",
    "ros",
    "cli",
    "api",
)

#: Third-party packages that only some floors may import (heavy or optional dependencies).
CONFINED = {
    "torch": ("rkmpc.learning.koopman.training", "rkmpc.learning.koopman.torch_ops"),
    "casadi": ("rkmpc.control.nonlinear.",),
    "acados": ("rkmpc.control.nonlinear.acados_build",),
    "matplotlib": ("rkmpc.analysis.",),
    "rich": ("rkmpc.cli", "rkmpc.analysis.tables"),
    "joblib": ("rkmpc.experiments.parallel",),
    "threadpoolctl": ("rkmpc.learning.learn",),
    "gymnasium": ("rkmpc.envs.f1tenth",),
    "rosbags": ("rkmpc.learning.data.bags.",),
    # ROS 2 (the optional ros extra): only the node modules; the core package never needs it.
    "rclpy": ("rkmpc.ros.",),
    "ackermann_msgs": ("rkmpc.ros.",),
    "nav_msgs": ("rkmpc.ros.",),
    "std_msgs": ("rkmpc.ros.",),
    "diagnostic_msgs": ("rkmpc.ros.",),
    "builtin_interfaces": ("rkmpc.ros.",),
    "yaml": ("rkmpc.config.loader",),
}


def module_name(path: Path, root: Path) -> str:
    """Dotted name of a source file under ``root`` (the ``rkmpc`` folder)."""
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def layer_of(module: str) -> str:
    """The floor of an ``rkmpc`` module."""
    parts = module.split(".")
    return "api" if len(parts) == 1 else parts[1]


def imports_of(source: str, module: str, known: set[str]) -> list[tuple[str, int]]:
    """``(imported module, line)`` of every import in ``source``; ``rkmpc`` ones resolved to modules."""
    tree = ast.parse(source)
    package = module if f"{module}.__init__" in known else module.rpartition(".")[0]
    found: list[tuple[str, int]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.extend((alias.name, node.lineno) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                target = f"{base}.{node.module}" if node.module else base
            else:
                target = node.module or ""
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                found.append((sub if sub in known else target, node.lineno))
    return found


def graph(root: Path) -> tuple[dict[str, list[tuple[str, int]]], dict[str, Path]]:
    """Import edges of every module of the package, and the file of each module."""
    files = {module_name(p, root): p for p in sorted(root.rglob("*.py"))}
    known = set(files) | {f"{m}.__init__" for m, p in files.items() if p.name == "__init__.py"}
    edges = {m: imports_of(p.read_text(), m, known) for m, p in files.items()}
    return edges, files


def arrows_up(edges: dict[str, list[tuple[str, int]]]) -> list[str]:
    """Every import of a higher floor (or of the package's public names from inside it)."""
    bad = []
    for module, targets in edges.items():
        low = LAYERS.index(layer_of(module))
        for target, line in targets:
            if target != "rkmpc" and not target.startswith("rkmpc."):
                continue
            if LAYERS.index(layer_of(target)) > low:
                bad.append(f"{module}:{line} imports {target} ({layer_of(module)} -> {layer_of(target)})")
    return bad


def cycles(edges: dict[str, list[tuple[str, int]]]) -> list[list[str]]:
    """The import circles among the package's modules (strongly connected components > 1, self-loops)."""
    nodes = sorted(edges)
    succ = {m: sorted({t for t, _ in edges[m] if t in edges}) for m in nodes}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:  # Tarjan's algorithm
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in succ[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1 or v in succ[v]:
                found.append(sorted(component))

    for v in nodes:
        if v not in index:
            visit(v)
    return found


def confinement(edges: dict[str, list[tuple[str, int]]]) -> list[str]:
    """Imports of a confined third-party package outside the modules allowed to use it."""
    bad = []
    for module, targets in edges.items():
        for target, line in targets:
            top = target.split(".")[0]
            allowed: Iterable[str] = CONFINED.get(top, ())
            if top in CONFINED and not any(module == a or module.startswith(a) for a in allowed):
                bad.append(f"{module}:{line} imports {target}")
    return bad


@pytest.fixture(scope="module")
def package_graph() -> dict[str, list[tuple[str, int]]]:
    return graph(PACKAGE)[0]


def test_every_module_sits_on_a_known_floor(package_graph):
    assert {layer_of(m) for m in package_graph} <= set(LAYERS)


def test_no_import_goes_up_a_floor(package_graph):
    assert arrows_up(package_graph) == []


def test_no_import_circle(package_graph):
    assert cycles(package_graph) == []


def test_heavy_and_optional_packages_stay_in_their_rooms(package_graph):
    assert confinement(package_graph) == []


#: The longest a module may be (lines), so one module stays one idea.
MAX_MODULE_LINES = 400


def long_modules(root: Path) -> list[str]:
    """Modules below ``root`` over :data:`MAX_MODULE_LINES` lines, with their length."""
    found = []
    for path in sorted(root.rglob("*.py")):
        lines = len(path.read_text().splitlines())
        if lines > MAX_MODULE_LINES:
            found.append(f"{path.relative_to(root)}: {lines} lines")
    return found


def pickle_uses(root: Path) -> list[str]:
    """Imports of ``pickle`` (or its relatives) below ``root``: nothing the package reads may run code."""
    found = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            found += [
                f"{path.relative_to(root)}:{node.lineno} imports {n}"
                for n in names
                if n.split(".")[0] in {"pickle", "cPickle", "dill", "cloudpickle", "shelve"}
            ]
    return found


def test_no_module_over_400_lines():
    assert long_modules(PACKAGE) == []


def test_no_pickle_in_the_package():
    assert pickle_uses(PACKAGE) == []


def test_the_size_and_pickle_checks_catch_a_long_module_and_a_pickle(tmp_path):
    root = tmp_path / "rkmpc"
    root.mkdir()
    (root / "long.py").write_text("x = 1\n" * (MAX_MODULE_LINES + 1))
    (root / "short.py").write_text("x = 1\n" * MAX_MODULE_LINES)
    (root / "unsafe.py").write_text("def load(f):\n    import pickle\n    return pickle.load(f)\n")
    assert long_modules(root) == [f"long.py: {MAX_MODULE_LINES + 1} lines"]
    assert pickle_uses(root) == ["unsafe.py:2 imports pickle"]


def _fake_package(tmp_path: Path, files: dict[str, str]) -> Path:
    root = tmp_path / "rkmpc"
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def test_the_checks_catch_an_arrow_up_and_a_circle(tmp_path):
    """The test would fail on a violation: a planted arrow up, a lazy one, a circle are all found."""
    root = _fake_package(
        tmp_path,
        {
            "__init__.py": "",
            "core/__init__.py": "",
            "core/io.py": "def f():\n    from rkmpc.sim.log import StepLog\n",
            "sim/__init__.py": "",
            "sim/log.py": "from rkmpc.core import io\nfrom . import run\n",
            "sim/run.py": "import rkmpc.sim.log\nimport torch\n",
            "track/__init__.py": "",
            "track/path.py": "if TYPE_CHECKING:\n    import rkmpc.track.x\n    import rkmpc.control.base\n",
        },
    )
    edges, _ = graph(root)
    up = arrows_up(edges)
    assert any(line.startswith("rkmpc.core.io:2 imports rkmpc.sim.log") for line in up)
    assert any("rkmpc.track.path:3 imports rkmpc.control.base" in line for line in up)
    assert not any("rkmpc.track.x" in line for line in up)  # the same floor is fine
    assert cycles(edges) == [["rkmpc.core.io", "rkmpc.sim.log", "rkmpc.sim.run"]]
    assert confinement(edges) == ["rkmpc.sim.run:2 imports torch"]


def test_importing_a_low_floor_loads_no_solver_or_torch():
    """``import rkmpc.track`` (and the control floor) must not load CasADi or PyTorch."""
    import subprocess
    import sys

    code = (
        "import sys, rkmpc.track.path, rkmpc.control, rkmpc.sim.closed_loop\n"
        "print(sorted(m for m in ('casadi', 'torch', 'matplotlib') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
