"""The package's layers run one way (docs/development.md): read from the source's imports.

Each folder (and each file) at the top of ``smartcar_gym`` is a node; an import of another
node's module, at module level or inside a function, is an edge. No circle may cross two
nodes; the layers the docs name hold; nothing reads another module's private names where the
issue that made tasks public said so; no module only re-exports another's names.
"""

from __future__ import annotations

import ast
import subprocess
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "smartcar_gym"
#: the public faces: a documented public path whose names live elsewhere (``Policy``, the
#: public API; the planar engine's 2D geometry, gathered from its four modules)
PUBLIC_FACES = {"smartcar_gym/policy.py", "smartcar_gym/sim/planar/geometry.py"}


def _node(module: str) -> str:
    parts = module.split(".")
    return parts[1].removesuffix(".py") if len(parts) > 1 else "smartcar_gym"


def _imports() -> dict[str, dict[str, set[str]]]:
    """node -> node it imports -> the files that import it."""
    edges: dict[str, dict[str, set[str]]] = defaultdict(lambda: defaultdict(set))
    for path in PACKAGE.rglob("*.py"):
        module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
        source = _node(module.removesuffix(".__init__"))
        for node in ast.walk(ast.parse(path.read_text())):
            names: list[str] = []
            if isinstance(node, ast.ImportFrom) and node.module == "smartcar_gym":
                names = [f"smartcar_gym.{a.name}" for a in node.names]
            elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith(
                    "smartcar_gym."):
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names if a.name.startswith("smartcar_gym.")]
            for name in names:
                target = _node(name)
                if target != source:
                    edges[source][target].add(str(path.relative_to(ROOT)))
    return edges


def _circles(edges: dict[str, dict[str, set[str]]]) -> list[list[str]]:
    """The strongly connected groups of more than one node (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in edges.get(v, {}):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for v in list(edges):
        if v not in index:
            visit(v)
    return found


def test_no_import_circle_crosses_two_folders_or_files():
    edges = _imports()
    circles = _circles(edges)
    detail = {tuple(c): {f"{a} -> {b}": sorted(edges[a][b]) for a in c for b in edges[a]
                         if b in c} for c in circles}
    assert not circles, detail


#: docs/development.md's layers, lowest first: a node imports only from its own layer or below
LAYERS = (
    {"checks", "extras", "parallel"},  # helpers any layer may use
    {"model", "controller"},
    {"sim"},
    {"navigation", "worlds"},
    {"envs", "registration"},
    {"viewers", "datasets", "bags", "runtime"},
    {"agents"},
    {"bench", "ros", "export", "scale", "calibration", "policy", "testing", "model_cli",
     "wrappers", "smartcar_gym"},  # the front ends, and the package's own __init__
)


def test_the_layers_hold():
    edges = _imports()
    layer = {node: i for i, nodes in enumerate(LAYERS) for node in nodes}
    nodes = {*edges, *(t for targets in edges.values() for t in targets)}
    assert nodes <= set(layer), f"place {sorted(nodes - set(layer))} in LAYERS"
    for node, targets in edges.items():
        wrong = {target: sorted(files) for target, files in targets.items()
                 if layer[target] > layer[node]}
        assert not wrong, f"{node} imports what sits above it: {wrong}"
    assert set(edges.get("model", {})) <= {"checks"}, edges.get("model")


def test_only_sim_imports_a_physics_library():
    for path in PACKAGE.rglob("*.py"):
        if "sim" in path.relative_to(PACKAGE).parts[:1]:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            assert not any(n.split(".")[0] in ("pybullet", "pybullet_data", "mujoco")
                           for n in names), path


def test_nothing_in_envs_reads_an_env_or_a_builder_s_private_names():
    # the issue's own check: no part of the envs reaches into another object's fields
    result = subprocess.run(["grep", "-rnE", r"\b(env|self\.env|builder|single)\._[a-z]",
                             str(PACKAGE / "envs"), "--include=*.py"],
                            capture_output=True, text=True)
    assert result.stdout == "", result.stdout


def test_no_module_only_re_exports_another_s_names():
    for path in PACKAGE.rglob("*.py"):
        name = str(path.relative_to(ROOT))
        if path.name == "__init__.py" or name in PUBLIC_FACES:
            continue
        tree = ast.parse(path.read_text())
        body = [n for n in tree.body if not (isinstance(n, ast.Expr)
                                             and isinstance(n.value, ast.Constant))]
        code = [n for n in body if not isinstance(n, ast.Import | ast.ImportFrom)
                and not (isinstance(n, ast.Assign) and any(
                    isinstance(t, ast.Name) and t.id == "__all__" for t in n.targets))]
        assert code or not body, f"{name} only imports (an alias module)"
        getattr_alias = any(isinstance(n, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "__getattr__" for t in n.targets)
            for n in tree.body)
        assert not getattr_alias, f"{name} forwards names with a module __getattr__"


def test_the_public_face_of_policy_is_the_agents_policies():
    import smartcar_gym.agents.policies as real
    import smartcar_gym.policy as face

    assert face.Policy is real.Policy and face.PolicyError is real.PolicyError
    for path in PACKAGE.rglob("*.py"):
        if str(path.relative_to(ROOT)) in PUBLIC_FACES:
            continue
        imported = {node.module for node in ast.walk(ast.parse(path.read_text()))
                    if isinstance(node, ast.ImportFrom)}  # code, not a docstring's example
        assert "smartcar_gym.policy" not in imported, \
            f"{path}: the package imports Policy from agents.policies, the real module"
