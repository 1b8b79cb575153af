"""Pure DAG functions on plain mappings."""
import pytest
from hypothesis import given
from hypothesis import strategies as st

from matrix import CycleError
from matrix.dag import critical_paths, dependents, find_cycle, graph_of, heights, in_order, subgraph, toposort
from matrix.jobs import Job
from tests.matrix import toydomain  # noqa: F401

GRAPH = {"report": ["eval1", "eval2"], "eval1": ["opt"], "eval2": ["opt", "data"], "opt": ["train"],
         "train": ["data"], "data": []}


def test_toposort_puts_dependencies_first():
    order = toposort(GRAPH)
    assert sorted(order) == sorted(GRAPH)
    assert all(order.index(dep) < order.index(node) for node, deps in GRAPH.items() for dep in deps)


def test_cycle_error_names_the_path():
    with pytest.raises(CycleError) as caught:
        toposort({"a": ["b"], "b": ["c"], "c": ["a"], "d": []})
    assert str(caught.value) == "dependency cycle: a -> b -> c -> a"


def test_find_cycle_none_and_self_loop():
    assert find_cycle(GRAPH) is None
    assert find_cycle({"a": ["a"]}) == ["a", "a"]


def test_dependents_and_subgraph():
    assert dependents(GRAPH, ["opt"]) == {"eval1", "eval2", "report"}
    assert dependents(GRAPH, ["report"]) == set()
    assert subgraph(GRAPH, ["eval1"]) == {"eval1": ["opt"], "opt": ["train"], "train": ["data"], "data": []}


def test_heights_count_the_longest_chain_waiting_on_a_node():
    assert heights(GRAPH) == {"data": 4, "train": 3, "opt": 2, "eval1": 1, "eval2": 1, "report": 0}


def test_critical_paths_add_a_node_s_cost_to_the_costliest_chain_waiting_on_it():
    assert critical_paths(GRAPH, lambda node: 1) == {node: h + 1 for node, h in heights(GRAPH).items()}
    seconds = {"report": 0, "eval1": 5, "eval2": 60, "opt": 10, "train": 30, "data": 4}
    path = critical_paths(GRAPH, seconds.__getitem__)
    assert path == {"report": 0, "eval1": 5, "eval2": 60, "opt": 70, "train": 100, "data": 104}
    # a short recording outranks a long lap nothing needs when what waits on it is longer still
    lab = {"lap": [], "training": ["recording"], "recording": []}
    assert critical_paths(lab, {"lap": 40, "training": 60, "recording": 5}.__getitem__)["recording"] == 65
    assert critical_paths(lab, {"lap": 40, "training": 30, "recording": 5}.__getitem__)["recording"] == 35


def test_graph_of_jobs_shares_equal_jobs():
    source = Job("source", "s", {"value": 1})
    twin = Job("source", "s again", {"value": 1})
    powers = [Job("power", f"p{i}", {"power": i}, deps={"source": s}) for i, s in ((2, source), (3, twin))]
    graph, by_key = graph_of(powers)
    assert len(graph) == 3
    assert graph[powers[0].key] == [source.key] == graph[powers[1].key]


dags = st.integers(1, 25).flatmap(lambda n: st.lists(st.lists(st.integers(0, n - 1), max_size=4),
                                                     min_size=n, max_size=n))


@given(dags)
def test_toposort_on_random_dags(edges):
    graph = {i: [j for j in deps if j < i] for i, deps in enumerate(edges)}  # edges to lower ids: acyclic
    order = toposort(graph)
    assert all(order.index(d) < order.index(n) for n, deps in graph.items() for d in deps)
    assert find_cycle(graph) is None
    height = heights(graph)
    assert all(height[d] > height[n] for n, deps in graph.items() for d in deps)
    path = critical_paths(graph, lambda node: node % 3 + 0.5)
    assert all(path[d] > path[n] for n, deps in graph.items() for d in deps)


@given(dags, st.lists(st.integers(0, 24), max_size=6))
def test_in_order_is_toposort_of_graph_of_in_one_pass(edges, roots):
    jobs: list[Job] = []
    # job i depends on lower ids; jobs 2k and k (k odd) have equal params (equal keys where their deps are too)
    for i, deps in enumerate(edges):
        jobs.append(Job("source", f"n{i}", {"value": i // 2 if i % 2 == 0 else i},
                        deps={f"d{k}": jobs[j] for k, j in enumerate(deps) if j < i}))
    chosen = [jobs[r % len(jobs)] for r in roots] or jobs
    graph, by_key = graph_of(chosen)
    assert [job.key for job in in_order(chosen)] == toposort(graph)
