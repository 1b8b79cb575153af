"""Pure functions over a job graph given as `{node: [dependencies]}` (as in Dask's task graphs).

`graph_of(jobs)` builds that mapping from Job objects (by key), pulling in every dependency;
`in_order(jobs)` lists them, dependencies first, without building it (a plan's one pass).
"""
from __future__ import annotations

from collections.abc import Callable, Hashable, Iterable, Mapping
from typing import Any

from matrix.errors import CycleError

Graph = Mapping[Hashable, Iterable[Hashable]]


def graph_of(jobs: Iterable) -> tuple[dict[str, list[str]], dict[str, object]]:
    """({key: [dep keys]}, {key: job}) for `jobs` and everything they depend on."""
    graph: dict[str, list[str]] = {}
    by_key: dict[str, object] = {}
    stack = list(reversed(list(jobs)))  # popped in the given order, so ties keep it
    while stack:
        job = stack.pop()
        if job.key in by_key:
            continue
        by_key[job.key] = job
        deps = job.dep_jobs()
        graph[job.key] = list(dict.fromkeys(d.key for d in deps))
        stack.extend(reversed(deps))
    return graph, by_key


def in_order(jobs: Iterable) -> list:
    """`jobs` and everything they depend on, each once (by key), every dependency before its dependents;
    ties keep the given order: the order of `toposort(graph_of(jobs)[0])`, in one pass. Jobs fix their
    dependencies when they are made (a job's key is made of its dependencies' keys), so they hold no cycle."""
    order, seen = [], set()
    for root in jobs:
        if root.key in seen:
            continue
        seen.add(root.key)
        stack = [(root, iter(root.dep_jobs()))]
        while stack:
            job, deps = stack[-1]
            for dep in deps:
                if dep.key not in seen:
                    seen.add(dep.key)
                    stack.append((dep, iter(dep.dep_jobs())))
                    break
            else:
                stack.pop()
                order.append(job)
    return order


def find_cycle(graph: Graph) -> list | None:
    """One cycle as a path [a, b, ..., a], or None."""
    state: dict = {}  # node -> "visiting" | "done"
    for root in graph:
        if root in state:
            continue
        path, iterators = [root], [iter(graph.get(root, ()))]
        state[root] = "visiting"
        while iterators:
            child = next(iterators[-1], _END)
            if child is _END:
                state[path.pop()] = "done"
                iterators.pop()
            elif state.get(child) == "visiting":
                return path[path.index(child):] + [child]
            elif child not in state:
                state[child] = "visiting"
                path.append(child)
                iterators.append(iter(graph.get(child, ())))
    return None


_END = object()


def toposort(graph: Graph) -> list:
    """Nodes with every dependency before its dependents; ties keep the graph's order.

    Raises CycleError naming the path of a cycle."""
    order, done = [], set()
    for root in graph:
        if root in done:
            continue
        stack = [(root, iter(graph.get(root, ())))]
        on_stack = {root}
        while stack:
            node, children = stack[-1]
            child = next(children, _END)
            if child is _END:
                stack.pop()
                on_stack.discard(node)
                done.add(node)
                order.append(node)
            elif child in on_stack:
                raise CycleError([str(n) for n in find_cycle(graph) or [child, child]])
            elif child not in done:
                stack.append((child, iter(graph.get(child, ()))))
                on_stack.add(child)
    return order


def dependents(graph: Graph, nodes: Iterable) -> set:
    """Every node that depends, directly or not, on any of `nodes` (excluding them)."""
    reverse: dict = {}
    for node, deps in graph.items():
        for dep in deps:
            reverse.setdefault(dep, []).append(node)
    seen, stack = set(), list(nodes)
    while stack:
        for parent in reverse.get(stack.pop(), ()):
            if parent not in seen:
                seen.add(parent)
                stack.append(parent)
    return seen - set(nodes)


def heights(graph: Graph) -> dict:
    """For each node, the length of the longest chain of nodes that depend on it (0: nothing does).

    A scheduler that starts the highest first keeps the critical path moving: a job that many
    stages wait on (a training) goes before a job nothing waits on (a report's reference lap)."""
    height = {node: 0 for node in graph}
    for node in reversed(toposort(graph)):   # every dependent comes before the nodes it needs
        for dep in graph.get(node, ()):
            height[dep] = max(height.get(dep, 0), height[node] + 1)
    return height


def critical_paths(graph: Graph, cost: Callable[[Any], float]) -> dict:
    """For each node, its own cost plus the costliest chain of nodes that depend on it (a list
    scheduler's "upward rank"): with every cost 1 it is `heights` + 1; with expected seconds a short
    recording that a long training waits on outranks a long lap that nothing needs."""
    order = toposort(graph)
    own = {node: float(cost(node)) for node in order}
    path = dict(own)
    for node in reversed(order):   # every dependent comes before the nodes it needs
        for dep in graph.get(node, ()):
            path[dep] = max(path[dep], own[dep] + path[node])
    return path


def subgraph(graph: Graph, targets: Iterable) -> dict:
    """The part of `graph` that `targets` need: the targets and all their dependencies."""
    result: dict = {}
    stack = list(targets)
    while stack:
        node = stack.pop()
        if node not in result:
            result[node] = list(graph.get(node, ()))
            stack.extend(result[node])
    return {node: result[node] for node in graph if node in result} | \
        {node: deps for node, deps in result.items() if node not in graph}
