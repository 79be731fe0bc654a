"""The package's layers, read from its import graph (grimp, the graph import-linter checks): every
import, those inside functions included, goes from a layer to its own or a lower one; the core
reaches no paper by any chain of imports; no module imports itself back through others."""

from __future__ import annotations

import grimp
import pytest

LAYERS = ("base", "model", "engines", "sources", "identify", "stages", "runner", "report")  # lowest first
TOP = ("api", "init", "cli", "pytest_plugin")
CORE = tuple(f"harness.{name}" for name in LAYERS + TOP)


@pytest.fixture(scope="module")
def graph():
    return grimp.build_graph("harness")  # imports for annotations included


def _layer(module: str) -> int | None:
    parts = module.split(".")
    if len(parts) < 2 or parts[1] in ("papers", "adapters"):
        return None
    name = parts[1]
    if name in LAYERS:
        return LAYERS.index(name)
    return len(LAYERS) if name in TOP else None


def test_every_import_goes_to_its_own_layer_or_below(graph):
    upward = [(a, b) for a in graph.modules for b in graph.find_modules_directly_imported_by(a)
              if _layer(a) is not None and _layer(b) is not None and _layer(b) > _layer(a)]
    assert upward == []


def test_the_core_reaches_no_paper_and_no_adapter_by_any_chain_of_imports(graph):
    reached = {m for core in CORE for m in graph.find_upstream_modules(core, as_package=True)}
    assert not {m for m in reached if m.startswith(("harness.papers", "harness.adapters"))}
    # and the graph does see the papers importing the core, so the check is not vacuous
    assert graph.chain_exists("harness.papers.graph_theory_2021.study", "harness.base.plugins")
    assert graph.chain_exists("harness.adapters.figaroh", "harness.base.plugins")


def test_no_module_imports_itself_back(graph):
    """Tarjan's strongly connected components of the module graph: each one module."""
    index, low, stack, on, cycles, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.find_modules_directly_imported_by(v):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph.modules):
        if v not in index:
            visit(v)
    assert cycles == []


def _stage_modules() -> set[str]:
    """The modules that define a registered core stage (a bench's and a log's)."""
    import inspect

    from harness.stages import core_stages, log_stages

    return {inspect.getmodule(stage.run).__name__ for stage in (*core_stages(), *log_stages())}


def test_no_stage_imports_another_stage_by_any_chain(graph):
    """A stage reads the results of those before it from the run's context, never their code: no stage
    module reaches another by any chain of imports (what stages share lives in modules that are no stage)."""
    stages = _stage_modules()
    assert len(stages) >= 8  # the check is not vacuous: every registered stage is in it
    reached = {(a, b) for a in stages for b in stages if a != b and graph.chain_exists(a, b)}
    assert reached == set()


def test_the_import_contract_lists_every_registered_stage():
    """pyproject.toml's independence contract (run by lint-imports in CI) names exactly the registered
    stages: a new stage cannot slip past it."""
    import tomllib
    from pathlib import Path

    config = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())
    contract = next(c for c in config["tool"]["importlinter"]["contracts"] if c["type"] == "independence")
    assert set(contract["modules"]) == _stage_modules()
