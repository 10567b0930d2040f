"""The package's layers import only downward: core (errors, atomic, fields,
jsonfiles, lazy, nn, progress, resume) -> data -> envs -> diffusion | rl | analysis -> pipelines | viz | api
(the public Python API) -> cli. Modules of one layer may import their own package, never a
sibling package of the same layer (diffusion, rl and analysis stay independent of each other, and
so do pipelines and viz)."""

import ast
import subprocess
import sys
from pathlib import Path

import xted

PACKAGE = Path(xted.__file__).parent
LAYERS = {
    "core": 0, "data": 1, "envs": 2, "diffusion": 3, "rl": 3, "analysis": 3, "pipelines": 4, "cli": 5,
    # Pictures draw on several layer-3 packages (analysis's spectra, the runs of diffusion and rl).
    "viz": 4,
    "api": 4,  # the module xted.api: the public names over layers 1-3
}
CORE_MODULES = {"__init__", "errors", "atomic", "fields", "jsonfiles", "lazy", "nn", "progress", "resume"}


def component(module: str) -> str:
    """``xted.rl.iql`` -> ``rl``; ``xted.errors`` -> ``core``."""
    parts = module.split(".")
    if len(parts) == 1 or parts[1] in CORE_MODULES:
        return "core"
    return parts[1]


def imported_modules(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
    return {name for name in found if name == "xted" or name.startswith("xted.")}


def test_every_component_has_a_layer():
    packages = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    modules = {p.stem for p in PACKAGE.glob("*.py")}
    assert packages <= set(LAYERS), packages - set(LAYERS)
    assert modules <= CORE_MODULES | {"api"}, modules - CORE_MODULES - {"api"}


def test_imports_point_down():
    violations = []
    for path in sorted(PACKAGE.rglob("*.py")):
        module = ".".join(("xted", *path.relative_to(PACKAGE).with_suffix("").parts))
        own = component(module)
        for imported in imported_modules(path):
            other = component(imported)
            if other == own:
                continue
            if LAYERS[other] >= LAYERS[own]:
                violations.append(f"{module} ({own}) imports {imported} ({other})")
    assert not violations, "\n".join(violations)


def test_editing_does_not_load_the_training_stack():
    code = ("import sys, xted.diffusion.editor; "
            "print(sorted(m for m in ('optax', 'orbax.checkpoint', 'xted.diffusion.training') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_the_cli_and_the_configs_load_without_jax():
    """`xted --help` stays fast: the CLI takes its defaults from plain-Python config modules."""
    code = ("import sys, xted.cli.main, xted.diffusion.config, xted.rl.config, xted.analysis.config, xted.viz.config; "
            "print(sorted(m for m in ('jax', 'flax', 'optax') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_lazy_exports_resolve_to_their_objects_not_to_a_submodule_of_the_same_name():
    import types

    import xted.analysis
    import xted.diffusion
    import xted.viz

    for package in (xted.analysis, xted.diffusion, xted.viz):
        for _ in range(2):  # the second pass runs with every submodule imported (bound on the package)
            for name in package.__all__:
                assert not isinstance(getattr(package, name), types.ModuleType), f"{package.__name__}.{name}"
