"""The layers run one way: the core (ecam) <- the rig (hil_sim) <- the application (ecam.app).

Read from the source (every import statement, those inside functions included), so an import
hidden in a function cannot bring a circle or a wrong-way dependency back.
"""

import ast
import importlib
import inspect
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("ecam", "hil_sim")
CAN_STACK = ("can", "canopen")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _sources() -> dict[str, Path]:
    return {_module_name(p): p for package in PACKAGES for p in sorted((ROOT / package).rglob("*.py"))}


def _imports(name: str, path: Path, known) -> set[str]:
    """Every module ``name`` imports (absolute names; ``from X import y`` imports X, and y too
    when y is a submodule)."""
    is_package = path.name == "__init__.py"
    package = name if is_package else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            submodules = {f"{target}.{a.name}" for a in node.names if f"{target}.{a.name}" in known}
            # `from . import x` imports x and runs its package: an edge to both (as
            # ../shared/tools/import_circles.py counts it).
            out.add(target)
            out.update(submodules)
    out.discard(name)
    return out


@pytest.fixture(scope="module")
def graph():
    sources = _sources()
    return {name: _imports(name, path, sources) for name, path in sources.items()}


def _layer(module: str) -> str:
    if module == "ecam.app" or module.startswith("ecam.app."):
        return "app"
    if module.split(".")[0] == "hil_sim":
        return "rig"
    return "core"


def _within(imported: str, prefix: str) -> bool:
    return imported == prefix or imported.startswith(prefix + ".")


def test_the_graph_sees_function_level_imports(graph):
    # The lazy dispatch of the CLI imports the rig commands inside a function: it must be seen.
    assert "ecam.app.rig_commands" in graph["ecam.app.cli"]


def test_no_import_circle_anywhere(graph):
    internal = {m: {t for t in targets if t in graph} for m, targets in graph.items()}
    index, low, stack, on_stack, circles = {}, {}, [], set(), []

    def visit(v):  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(internal[v]):
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
            if len(component) > 1:
                circles.append(sorted(component))

    for module in sorted(internal):
        if module not in index:
            visit(module)
    assert circles == []


@pytest.mark.parametrize("forbidden", ["hil_sim", "ecam.app", *CAN_STACK, "matplotlib"])
def test_the_core_imports_no_rig_no_application_no_can_and_plots_only_at_its_edge(graph, forbidden):
    offenders = {
        module: sorted(t for t in targets if _within(t, forbidden))
        for module, targets in graph.items()
        if _layer(module) == "core" and not (forbidden == "matplotlib" and module == "ecam.plot")
    }
    assert {m: t for m, t in offenders.items() if t} == {}


def test_the_rig_never_imports_the_application(graph):
    offenders = {m: sorted(t for t in targets if _layer(t) == "app" and t.startswith("ecam"))
                 for m, targets in graph.items() if _layer(m) == "rig"}
    assert {m: t for m, t in offenders.items() if t} == {}


def test_importing_ecam_loads_no_can_stack_no_plotting_no_rig():
    code = ("import sys, ecam, ecam.compile, ecam.export, ecam.design, ecam.mechanics, ecam.validate; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('can', 'canopen', 'matplotlib', 'scipy', 'hil_sim') or m.startswith('ecam.app')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def _loaded_after(statement: str) -> list[str]:
    """The heavy or wrong-layer modules a fresh interpreter has loaded after ``statement``."""
    code = (f"import sys; {statement}; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('can', 'canopen', 'matplotlib', 'scipy', 'ruckig') or m.startswith('ecam.app')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return ast.literal_eval(out.stdout)


def test_importing_hil_sim_loads_no_can_stack_until_a_rig_name_is_used():
    # Every `ecam` command imports hil_sim (for SCENES_DIR); the CAN stack, ruckig and the
    # plotting come in with the first rig name used.
    assert _loaded_after("import hil_sim; hil_sim.SCENES_DIR") == []
    loaded = _loaded_after("import hil_sim; hil_sim.run_scene")
    assert {"can", "canopen"} <= set(loaded), "the check above would not see the CAN stack"


def test_reading_a_scene_loads_no_can_stack():
    # A scene's fault plan and its 0x60C2 cycle are checked without python-can or canopen, so a
    # job that only validates its scenes stays light: every shipped scene, and one with faults.
    loaded = _loaded_after(
        "import tomllib, hil_sim; "
        "[hil_sim.load_scene(p) for p in sorted(hil_sim.SCENES_DIR.glob('*.toml'))]; "
        "data = tomllib.loads((hil_sim.SCENES_DIR / 'stiff_coupling.toml').read_text()); "
        "data['bus']['faults'] = {'seed': 2, 'drop_probability': 0.1, 'drop': [{'cycle': 5, 'frame': 'sync'}]}; "
        "scene = hil_sim.parse_scene(data, base=hil_sim.SCENES_DIR); "
        "assert scene.bus.faults.drop == ((5, 'sync'),) and scene.bus.faults.active")
    assert loaded == []
    assert {"can", "canopen"} <= set(_loaded_after("import hil_sim.bus")), "the check would not see the CAN stack"


def test_the_firmware_generator_loads_no_can_and_no_plotting():
    loaded = _loaded_after("import ecam.app.firmware")
    assert "ecam.app.firmware" in loaded, "the check would not see what the import loaded"
    assert [m for m in loaded if not m.startswith("ecam.app")] == []


# Public names: each package's __all__ names, read the way help() shows them.
EXPORTING = ("ecam", "hil_sim", "ecam.export")


def _exported(package: str):
    module = importlib.import_module(package)
    return [(name, getattr(module, name)) for name in module.__all__]


def _own_docstring(obj) -> str:
    doc = getattr(obj, "__doc__", None) or ""
    if inspect.isclass(obj) and doc.startswith(f"{obj.__name__}("):
        return ""  # the signature a dataclass writes when its class has no docstring
    return doc.strip()


@pytest.mark.parametrize("package", EXPORTING)
def test_every_exported_function_class_and_module_has_a_docstring(package):
    undocumented = [name for name, obj in _exported(package)
                    if (inspect.isclass(obj) or inspect.isroutine(obj) or inspect.ismodule(obj))
                    and not _own_docstring(obj)]
    assert undocumented == []


@pytest.mark.parametrize("package", EXPORTING)
def test_every_exported_constant_is_described_in_its_package_docstring(package):
    # A tuple, dict or path cannot carry a docstring of its own: the package's says what it is.
    doc = importlib.import_module(package).__doc__
    undocumented = [name for name, obj in _exported(package)
                    if not (inspect.isclass(obj) or inspect.isroutine(obj) or inspect.ismodule(obj))
                    and f"``{name}``" not in doc]
    assert undocumented == []
