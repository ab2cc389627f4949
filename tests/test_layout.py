"""The package layout: each package imports only the ones below it, and docs/architecture.md's
tree lists every module of the package."""

import ast
import re
from pathlib import Path

from conftest import REPO

PACKAGE = REPO / "footforge"
LOW = "low"  # the modules directly in footforge/ (errors, units, provenance, ...)
ALLOWED = {
    LOW: {LOW},
    "inputs": {LOW},
    "models": {LOW, "inputs"},
    "mjcf": {LOW, "inputs", "models"},
    "usd": {LOW, "models"},
    "build": {LOW, "inputs", "models", "mjcf", "usd"},
    "envs": {LOW},  # environments read a build from disk; they never run the build
    "validate": {LOW, "inputs", "models", "mjcf", "envs"},
    "rl": {LOW, "envs"},
    "cli": {LOW, "inputs", "models", "mjcf", "usd", "build", "envs", "validate", "rl"},
}
"""Package -> the packages its modules may import (besides their own)."""


def _package_of(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and (PACKAGE / parts[1]).is_dir() else LOW


def _imports(path: Path) -> set[str]:
    """Every footforge module `path` imports, at the top or inside functions."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "footforge":
            if node.module == "footforge":
                out |= {f"footforge.{a.name}" for a in node.names}
            else:
                out.add(node.module)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.split(".")[0] == "footforge"}
    return out


def _modules() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def test_packages_import_only_the_layers_below():
    assert set(ALLOWED) == {LOW} | {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file()}
    upward = []
    for path in _modules():
        module = ".".join(path.relative_to(REPO).with_suffix("").parts)
        source = _package_of(module)
        for imported in _imports(path):
            target = _package_of(imported)
            if target != source and target not in ALLOWED[source]:
                upward.append(f"{path.relative_to(REPO)} imports {imported} ({source} -> {target})")
    assert not upward, "\n".join(upward)


def test_the_layering_check_sees_an_upward_import(tmp_path):
    """The check above can fail: a function-level import of the build pipeline is found."""
    module = tmp_path / "m.py"
    module.write_text("def f():\n    from footforge.build.pipeline import build\n    from footforge import envs\n")
    assert _imports(module) == {"footforge.build.pipeline", "footforge.envs"}
    assert _package_of("footforge.build.pipeline") == "build" and "build" not in ALLOWED["envs"]


def test_architecture_page_lists_every_module():
    page = (REPO / "docs" / "architecture.md").read_text()
    section = page[page.index("## The package") :]
    tree = section[section.index("```") + 3 :]
    tree = tree[: tree.index("```")]
    listed, folder = set(), None
    for line in tree.splitlines()[1:]:
        match = re.match(r"^( +)(\S+)", line)
        if not match:
            continue
        indent, name = len(match.group(1)), match.group(2)
        if name.endswith("/"):
            folder = name[:-1] if indent == 2 else folder
        else:
            listed.add(f"{folder}/{name}" if indent == 4 else name)
    actual = {str(p.relative_to(PACKAGE)) for p in _modules() if not (p.name == "__init__.py" and p.parent != PACKAGE)}
    assert listed == actual, (
        f"missing from docs/architecture.md: {sorted(actual - listed)}; listed but absent: {sorted(listed - actual)}"
    )


def test_the_package_exports_its_entry_points_lazily():
    """`import footforge` loads neither MuJoCo nor JAX, nor does the environments' configuration;
    the entry points load on first use."""
    import subprocess
    import sys

    code = (
        "import sys, footforge; assert 'mujoco' not in sys.modules and 'jax' not in sys.modules; "
        "import footforge.envs.config; assert 'jax' not in sys.modules; "
        "from footforge.build.pipeline import BuildOptions; from footforge.envs import make; "
        "from footforge.rl.train import load_policy; "
        "assert footforge.BuildOptions is BuildOptions and footforge.make_env is make "
        "and footforge.load_policy is load_policy; print(sorted(footforge.__all__))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "ValidateOptions" in out.stdout and "check_description" in out.stdout


def test_each_enumeration_is_spelled_once():
    """Foot variants, feet and policy types are declared in footforge/variants.py; a tuple, list or
    set of three or more of their names anywhere else in footforge/ or benchmarks/, or of two in a
    membership test (`x in ("aof", "aff")`), is a second list to keep in step. (A default chosen
    among them, e.g. a benchmark's ["B", "PH"], is a choice, not a list.)"""
    groups = ({"full", "aof", "aff", "ball"}, {"B", "BH", "P", "PH"})
    found = []
    for path in [*(REPO / "footforge").rglob("*.py"), *(REPO / "benchmarks").glob("*.py")]:
        if path.name == "variants.py" and path.parent.name == "footforge":
            continue
        tree = ast.parse(path.read_text())
        tested = {
            id(c)
            for n in ast.walk(tree)
            if isinstance(n, ast.Compare) and any(isinstance(op, (ast.In, ast.NotIn)) for op in n.ops)
            for c in n.comparators
        }
        for node in ast.walk(tree):
            if isinstance(node, (ast.Tuple, ast.List, ast.Set)) and len(node.elts) >= (2 if id(node) in tested else 3):
                names = {e.value for e in node.elts if isinstance(e, ast.Constant)}
                if len(names) == len(node.elts) and any(names <= g for g in groups):
                    found.append(f"{path.relative_to(REPO)}:{node.lineno} {sorted(names)}")
    assert not found, "import these from footforge.variants:\n" + "\n".join(found)


def _import_graph(package: Path) -> dict[str, set[str]]:
    """module -> the modules of `package` it imports (at the top, inside functions or for type
    checking alike); `from package.sub import name` counts as importing package.sub.name where that
    is a module, else package.sub."""
    root = package.parent

    def name_of(path: Path) -> str:
        parts = path.relative_to(root).with_suffix("").parts
        return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)

    modules = {name_of(p): p for p in package.rglob("*.py") if "__pycache__" not in p.parts}

    def known(name: str) -> str:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name

    graph = {}
    for module, path in modules.items():
        out = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if (
                isinstance(node, ast.ImportFrom)
                and node.level == 0
                and node.module
                and node.module.split(".")[0] == package.name
            ):
                out |= {
                    f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in modules else known(node.module)
                    for a in node.names
                }
            elif isinstance(node, ast.Import):
                out |= {known(a.name) for a in node.names if a.name.split(".")[0] == package.name}
        graph[module] = out - {module, ""}
    return graph


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import circles: each strongly connected group of two or more modules (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while not group or group[-1] != v:
                group.append(stack.pop())
                on_stack.discard(group[-1])
            if len(group) > 1:
                found.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_module_imports_itself_round_a_circle():
    """No import circle in footforge/: e.g. the term modules (envs.rewards, envs.observations)
    import nothing from the configuration that declares their terms (envs.config)."""
    graph = _import_graph(PACKAGE)
    assert "footforge.envs.config" not in graph["footforge.envs.rewards"] | graph["footforge.envs.observations"]
    assert not _circles(graph), _circles(graph)


def test_the_circle_check_sees_a_circle(tmp_path):
    """The check above can fail: a circle through a function-level import is found, a chain is not."""
    package = tmp_path / "pkg"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "sub" / "__init__.py").write_text("")
    (package / "sub" / "a.py").write_text("from pkg.sub import b\n")
    (package / "sub" / "b.py").write_text("def f():\n    from pkg.sub.c import name\n")
    (package / "sub" / "c.py").write_text("import pkg.sub.a\nname = 1\n")
    (package / "d.py").write_text("from pkg.sub import a\n")
    graph = _import_graph(package)
    assert graph["pkg.sub.b"] == {"pkg.sub.c"} and graph["pkg.d"] == {"pkg.sub.a"}
    assert _circles(graph) == [["pkg.sub.a", "pkg.sub.b", "pkg.sub.c"]]


def test_private_mjx_state_is_read_only_in_its_adapter():
    """`mujoco.mjx._src` and the `_impl` fields of MJX's Model and Data are used in
    footforge/envs/mjx_private.py alone (tests/test_mjx_private.py pins them)."""
    private = re.compile(r"mjx\._src|\._impl\b|\b_impl=")
    found = [
        f"{p.relative_to(REPO)}:{n}"
        for p in _modules()
        if p != PACKAGE / "envs" / "mjx_private.py"
        for n, line in enumerate(p.read_text().splitlines(), 1)
        if private.search(line)
    ]
    assert not found, "read MJX's private state through footforge.envs.mjx_private:\n" + "\n".join(found)
    assert private.search("support = mujoco.mjx._src.support") and private.search("data._impl.contact")


README_WORDS = 1200
"""The README's length limit (issue 47: one screen or two; Playground's is about 700 words)."""


def test_the_readme_stays_within_its_word_limit():
    """The README is counted as `wc -w` counts it (whitespace-separated words, tables and commands
    included): at most README_WORDS; what does not fit goes to docs/."""
    words = len((REPO / "README.md").read_text().split())
    assert 300 < words <= README_WORDS, f"README.md has {words} words (limit {README_WORDS}): move detail to docs/"
