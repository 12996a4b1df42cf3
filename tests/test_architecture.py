"""The house as docs/architecture.md draws it, read from the source (no module is imported here but the study
registry): no import cycle, no import up a layer, one folder per study, no private name taken from another
module, and a long module says why it is one.

Every import counts, at module level or inside a function (a lazy import is still an arrow); imports under
``if TYPE_CHECKING:`` do not run and do not count."""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "surgopt"

#: Layers, lowest first: a module may import its own layer and those below it, never one above.
LAYERS = (
    ("base", ("surgopt._version", "surgopt.errors", "surgopt.files", "surgopt.config", "surgopt.jit",
              "surgopt.parts", "surgopt.metrics", "surgopt.code_identity", "surgopt.interrupts")),
    ("robots", ("surgopt.robots",)),
    ("kinematics", ("surgopt.kinematics",)),
    ("plans", ("surgopt.plans",)),
    ("studies", ("surgopt.studies",)),
    ("orchestration", ("surgopt",)),  # config-to-rows machinery, the store, reports, the CLI, the API
)


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in PACKAGE.rglob("*.py")}


def layer(module: str) -> int:
    for rank, (_, prefixes) in enumerate(LAYERS):
        if any(module == p or module.startswith(p + ".") for p in prefixes):
            return rank
    raise AssertionError(module)


def _owner(name: str) -> str | None:
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """ids of the nodes under ``if TYPE_CHECKING:``."""
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and getattr(node.test, "id", getattr(node.test, "attr", None)) == "TYPE_CHECKING":
            skip.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    return skip


def imports(module: str) -> list[tuple[str, str, int]]:
    """(imported module, the name taken from it or '', line) of every import of the package in ``module``."""
    path = MODULES[module]
    tree = ast.parse(path.read_text())
    skip = _type_checking_nodes(tree)
    out = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            out += [(_owner(a.name), "", node.lineno) for a in node.names if a.name.split(".")[0] == "surgopt"]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                pkg = module if path.name == "__init__.py" else module.rpartition(".")[0]
                for _ in range(node.level - 1):
                    pkg = pkg.rpartition(".")[0]
                base = f"{pkg}.{base}" if base else pkg
            if base.split(".")[0] != "surgopt":
                continue
            for a in node.names:
                sub = f"{base}.{a.name}"
                out.append((sub, "", node.lineno) if sub in MODULES else (_owner(base), a.name, node.lineno))
    return [(m, n, line) for m, n, line in out if m and m != module]


GRAPH = {m: sorted({t for t, _, _ in imports(m)}) for m in MODULES}


def cycles(graph: dict[str, list[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, found, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_the_cycle_finder_finds_a_cycle():
    """The premise of the next test: a two-module and a three-module cycle are found, a chain is not."""
    assert cycles({"a": ["b"], "b": ["a"], "c": ["d"], "d": ["e"], "e": ["c"], "f": ["a"]}) == [["a", "b"],
                                                                                                 ["c", "d", "e"]]
    assert cycles({"a": ["b"], "b": ["c"], "c": []}) == []


def test_the_import_graph_has_no_cycle():
    assert len(GRAPH) > 80 and sum(map(len, GRAPH.values())) > 200  # the premise: the graph was read
    assert cycles(GRAPH) == []


def test_no_module_imports_a_layer_above_its_own():
    upward = [f"{m} ({LAYERS[layer(m)][0]}) imports {t} ({LAYERS[layer(t)][0]}), line {line}"
              for m in MODULES for t, _, line in imports(m) if layer(t) > layer(m)]
    assert upward == []


def test_no_module_takes_a_private_name_from_another():
    private = [f"{m} takes {name} from {t}, line {line}" for m in MODULES for t, name, line in imports(m)
               if name.startswith("_") and not name.startswith("__")]
    assert private == []


def test_each_study_is_one_folder_with_its_declaration_figures_and_page():
    from surgopt.studies import STUDIES, get_study

    for name, module in STUDIES.items():
        folder = module.rpartition(".")[0]
        assert module == f"{folder}.study" and (PACKAGE.parent / folder.replace(".", "/") / "__init__.py").is_file()
        study = get_study(name)
        for hook in (study.figures, study.html_views):  # declared by module name, loaded on first use
            (target,) = [c.cell_contents for c in hook.__closure__ if isinstance(c.cell_contents, str)]
            assert target in MODULES and target.rpartition(".")[0].startswith("surgopt.studies."), (name, target)
    loose = [m for m in MODULES if m.startswith("surgopt.studies.") and m.count(".") == 2
             and MODULES[m].name != "__init__.py"
             and m not in ("surgopt.studies.plotting", "surgopt.studies.page")]  # what every study draws with
    assert loose == []  # nothing of a study outside its folder


def test_a_module_past_600_lines_says_why_it_is_one_module():
    long = [m for m, p in MODULES.items() if len(p.read_text().splitlines()) > 600
            and "one module" not in " ".join(p.read_text().splitlines()[:40]).lower()]
    assert long == []


def test_every_file_a_config_names_is_a_file_field_that_layered_configs_resolve():
    """A field read through ``files.resolve_and_hash`` names a file relative to its config's folder; a layered
    config (several CONFIG files) takes each layer's from its own folder by ``files.FILE_FIELDS``: every such
    field must be listed there."""
    import re

    listed = next(node.value for node in ast.parse((PACKAGE / "files.py").read_text()).body
                  if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "FILE_FIELDS")
    FILE_FIELDS = ast.literal_eval(listed)
    named = set()
    for path in PACKAGE.rglob("*.py"):
        text = path.read_text()
        named |= set(re.findall(r'resolve_and_hash\(\w+, "(\w+)"', text))
        named |= set(re.findall(r'_resolved\("(\w+)"', text))
    assert named and named <= set(FILE_FIELDS), sorted(named - set(FILE_FIELDS))


#: Where a cart's kind may be compared with a name (issue 53): the platform registry and the cart classes (and the
#: config's own "auto", which the registry resolves).
CART_KIND_HOMES = {"surgopt.robots.dvrk.platforms", "surgopt.studies.port_place.carts"}
CART_KINDS = {"none", "classic", "si"}


def _cart_kind_comparisons(tree: ast.AST) -> list[int]:
    """Lines comparing something that reads a cart's kind (``.cart.model``, ``cart_of(...)``, ``suj_family``) with
    one of the carts' names, by ==, != or in."""
    def reads_kind(node) -> bool:
        if isinstance(node, ast.Attribute):
            return node.attr in ("suj_family",) or (node.attr == "model" and isinstance(node.value, ast.Attribute)
                                                    and node.value.attr == "cart")
        return isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "cart_of"

    def names_kind(node) -> bool:
        consts = [node] if isinstance(node, ast.Constant) else getattr(node, "elts", [])
        return any(isinstance(c, ast.Constant) and c.value in CART_KINDS for c in consts)

    return [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Compare)
            and any(reads_kind(x) for x in (n.left, *n.comparators))
            and any(names_kind(x) for x in (n.left, *n.comparators))]


def test_no_module_branches_on_a_carts_name_outside_the_registry_and_the_cart_classes():
    found = {m: _cart_kind_comparisons(ast.parse(p.read_text())) for m, p in MODULES.items() if m not in CART_KIND_HOMES}
    assert not {m: lines for m, lines in found.items() if lines}
    probe = ast.parse('if cfg.cart.model == "si": pass\nif cart_of(c) != "none": pass\nif x.model == "si": pass')
    assert _cart_kind_comparisons(probe) == [1, 2]  # the premise: the finder finds them


#: Where an arm's kind (an RCM mechanism, or a serial arm keeping the RCM in software) may be read (issue 53): the
#: config that declares the fields, the arm classes that hold the difference, and the serial arm's own tables
#: (which read the arm's stance and radius from its section).
ARM_KIND_HOMES = {"surgopt.studies.port_place.config", "surgopt.studies.port_place.arms",
                  "surgopt.studies.port_place.serial_arms", "surgopt.studies.port_place.arm_config"}
ARM_KIND_FIELDS = {"instrument_serial", "camera_serial"}


def _arm_kind_reads(tree: ast.AST) -> list[int]:
    """Lines reading which kind of arm a config has: ``.instrument_serial`` / ``.camera_serial`` as attributes, or
    their names as strings (a stored config's ``.get("instrument_serial")``)."""
    return sorted({n.lineno for n in ast.walk(tree)
                   if (isinstance(n, ast.Attribute) and n.attr in ARM_KIND_FIELDS)
                   or (isinstance(n, ast.Constant) and n.value in ARM_KIND_FIELDS)})


def test_no_module_reads_an_arms_kind_outside_the_arm_classes():
    port_place = {m: p for m, p in MODULES.items() if m.startswith("surgopt.studies.port_place.")}
    assert len(port_place) > 10  # the premise: port-place's modules were found
    found = {m: _arm_kind_reads(ast.parse(p.read_text())) for m, p in port_place.items() if m not in ARM_KIND_HOMES}
    assert not {m: lines for m, lines in found.items() if lines}
    probe = ast.parse('if cfg.robot.instrument_serial is None: pass\nx = robot.get("camera_serial")\ny = "serial"')
    assert _arm_kind_reads(probe) == [1, 2]  # the premise: the finder finds them


#: port-place's views (issue 53: "the views import no kernel and never rebuild a pose themselves: they read a
#: ``Layout`` from ``layout.py``"): the closing report, the figures, the page, the robot files.
VIEWS = tuple(f"surgopt.studies.port_place.{m}" for m in ("report", "figures", "html", "scene", "export"))


def kernels() -> set[str]:
    """The kernel modules: those under ``surgopt.kinematics`` that compile with numba (import ``surgopt.jit``).
    The vocabulary modules beside them (``kinematics/port/reasons.py``, ``columns.py``: plain constants) are not."""
    return {m for m in MODULES if m.startswith("surgopt.kinematics.")
            and any(imported == "surgopt.jit" for imported, _, _ in imports(m))}


def test_no_view_imports_a_kernel_nor_docks_a_layout_itself():
    ks = kernels()
    assert {"surgopt.kinematics.port.suj_batch", "surgopt.kinematics.port.place"} <= ks  # the premise
    assert "surgopt.kinematics.port.reasons" not in ks and "surgopt.kinematics.port.columns" not in ks
    for view in VIEWS:
        taken = imports(view)
        assert not [(m, line) for m, _, line in taken if m in ks], view
        # a layout's docking is solved in one place (layout.layout_of), not by each view
        assert not [(m, n, line) for m, n, line in taken if n in ("docking_that_clears", "docked_arms",
                                                                    "row_patient_in_cart")], view
