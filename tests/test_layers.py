"""The layering rules of the package, read from the sources with ``ast``.

1. No import cycles (module-level or function-local imports alike), so no function-local import
   dodges one; no use of another module's ``_private`` name.
2. ``kernels/`` imports nothing of rodnet outside itself; no numba outside ``kernels/``.
3. ``integrate/`` imports neither ``models/``, ``contact/`` nor ``config``.
4. ``models/`` and ``contact/`` never import ``integrate/``; ``contact/`` never imports
   ``models/``, and of ``models/`` only the registry and the system it builds import ``contact/``.
5. ``io/`` never imports ``models/`` or ``contact/``; the plain data (``config``, ``scene``,
   ``topology``, ``errors``, ``state``) imports only each other.

Every rule is checked on the package and shown to fail on a tree with a deliberately bad import.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "rodnet"
PLAIN = ("rodnet.config", "rodnet.scene", "rodnet.topology", "rodnet.errors", "rodnet.state")
COMPOSERS = ("rodnet.models.registry", "rodnet.models.system")


def _module_name(root: Path, path: Path) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(root: Path) -> dict[str, list[tuple[str, str | None]]]:
    """module -> [(imported module, imported name or None)] for every import in its source."""
    modules = {_module_name(root, p): p for p in root.rglob("*.py")}
    found: dict[str, list[tuple[str, str | None]]] = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text())
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        edges: list[tuple[str, str | None]] = []
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                edges += [(a.name, None) for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[: len(package.split(".")) - node.level + 1]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                for a in node.names:
                    full = f"{target}.{a.name}"
                    edges.append((full, None) if full in modules else (target, a.name))
        found[name] = edges
    return found


def _private_attributes(root: Path) -> list[str]:
    """``module._name`` uses of another module's private name (a module of the package)."""
    found = []
    for path in root.rglob("*.py"):
        name = _module_name(root, path)
        tree = ast.parse(path.read_text())
        aliases = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith(root.name):
                aliases.update({a.asname or a.name: f"{node.module}.{a.name}" for a in node.names})
            elif isinstance(node, ast.Import):
                aliases.update({a.asname or a.name: a.name for a in node.names
                                if a.name.startswith(root.name)})
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in aliases and node.attr.startswith("_")
                    and not node.attr.startswith("__") and aliases[node.value.id] != name):
                found.append(f"{name} uses {aliases[node.value.id]}.{node.attr}")
    return found


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
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
                out.append(sorted(component))

    for v in list(graph):
        if v not in index:
            visit(v)
    return out


def _inside(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def violations(root: Path) -> list[str]:
    """Every broken rule of the package at ``root``, as readable lines."""
    imports = _imports(root)
    modules = set(imports)
    top = root.name
    graph = {m: {t for t, _ in edges if t in modules and t != m} for m, edges in imports.items()}
    found = [f"rule 1: import cycle {c}" for c in _cycles(graph)]
    for m, edges in imports.items():
        for target, name in edges:
            if name and name.startswith("_") and not name.startswith("__") and _inside(target, top):
                found.append(f"rule 1: {m} imports the private {target}.{name}")
    found += [f"rule 1: {line}" for line in _private_attributes(root)]
    for m, edges in imports.items():
        targets = [t for t, _ in edges]
        ours = [t for t in targets if _inside(t, top)]
        if _inside(m, f"{top}.kernels"):
            found += [f"rule 2: {m} imports {t}" for t in ours
                      if not _inside(t, f"{top}.kernels") and t != top]
        elif any(t == "numba" or t.startswith("numba.") for t in targets):
            found.append(f"rule 2: {m} imports numba outside kernels/")
        if _inside(m, f"{top}.integrate"):
            found += [f"rule 3: {m} imports {t}" for t in ours
                      if any(_inside(t, f"{top}.{p}") for p in ("models", "contact", "config"))]
        if _inside(m, f"{top}.models") or _inside(m, f"{top}.contact"):
            found += [f"rule 4: {m} imports {t}" for t in ours if _inside(t, f"{top}.integrate")]
        if _inside(m, f"{top}.contact"):
            found += [f"rule 4: {m} imports {t}" for t in ours if _inside(t, f"{top}.models")]
        if _inside(m, f"{top}.models") and m.replace(top, "rodnet", 1) not in COMPOSERS:
            found += [f"rule 4: {m} imports {t} (only the registry composes contact)"
                      for t in ours if _inside(t, f"{top}.contact")]
        if _inside(m, f"{top}.io"):
            found += [f"rule 5: {m} imports {t}" for t in ours
                      if _inside(t, f"{top}.models") or _inside(t, f"{top}.contact")]
        plain = [p.replace("rodnet", top, 1) for p in PLAIN]
        if m in plain:
            found += [f"rule 5: {m} imports {t}" for t in ours if t not in plain and t != top]
    return found


def test_the_package_keeps_its_layers() -> None:
    assert violations(PACKAGE) == []


BAD = {
    "rule 1": {"a.py": "from pkg import b\n", "b.py": "def f():\n    from pkg import a\n"},
    "rule 1 ": {"a.py": "from pkg.b import _hidden\n", "b.py": "_hidden = 1\n"},
    "rule 1  ": {"a.py": "from pkg import b\nx = b._hidden\n", "b.py": "_hidden = 1\n"},
    "rule 2": {"kernels/k.py": "from pkg.models import m\n", "models/m.py": ""},
    "rule 2 ": {"integrate/i.py": "import numba\n"},
    "rule 3": {"integrate/i.py": "from pkg.contact import term\n", "contact/term.py": ""},
    "rule 3 ": {"integrate/i.py": "from pkg import config\n", "config.py": ""},
    "rule 4": {"models/m.py": "from pkg.integrate import i\n", "integrate/i.py": ""},
    "rule 4 ": {"models/lumped.py": "from pkg.contact import term\n", "contact/term.py": ""},
    "rule 5": {"io/vtk.py": "from pkg.models import m\n", "models/m.py": ""},
    "rule 5 ": {"topology.py": "from pkg.io import vtk\n", "io/vtk.py": ""},
}


@pytest.mark.parametrize("rule", list(BAD))
def test_a_bad_import_breaks_its_rule(rule: str, tmp_path: Path) -> None:
    root = tmp_path / "pkg"
    for name, text in {"__init__.py": "", **BAD[rule]}.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        for parent in path.relative_to(root).parents:
            (root / parent / "__init__.py").touch()
        path.write_text(text)
    found = violations(root)
    assert found and all(line.startswith(rule.strip()) for line in found), found
