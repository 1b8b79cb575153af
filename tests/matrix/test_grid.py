"""expand_grid against the GitHub Actions documentation, plus properties."""
import itertools

import pytest
from hypothesis import given
from hypothesis import strategies as st

from matrix import RecipeError
from matrix.grid import describe_alike, expand_classes, expand_grid


def test_product_in_declared_order_last_axis_fastest():
    # docs: "Using a matrix strategy" — version x os
    grid = expand_grid({"version": [10, 12, 14], "os": ["ubuntu-latest", "windows-latest"]})
    assert grid == [
        {"version": 10, "os": "ubuntu-latest"}, {"version": 10, "os": "windows-latest"},
        {"version": 12, "os": "ubuntu-latest"}, {"version": 12, "os": "windows-latest"},
        {"version": 14, "os": "ubuntu-latest"}, {"version": 14, "os": "windows-latest"},
    ]


def test_docs_example_expanding_or_adding_configurations():
    grid = expand_grid({
        "fruit": ["apple", "pear"], "animal": ["cat", "dog"],
        "include": [{"color": "green"}, {"color": "pink", "animal": "cat"},
                    {"fruit": "apple", "shape": "circle"}, {"fruit": "banana"},
                    {"fruit": "banana", "animal": "cat"}]})
    assert grid == [
        {"fruit": "apple", "animal": "cat", "color": "pink", "shape": "circle"},
        {"fruit": "apple", "animal": "dog", "color": "green", "shape": "circle"},
        {"fruit": "pear", "animal": "cat", "color": "pink"},
        {"fruit": "pear", "animal": "dog", "color": "green"},
        {"fruit": "banana"},
        {"fruit": "banana", "animal": "cat"},
    ]


def test_docs_example_include_adds_to_one_combination():
    grid = expand_grid({"os": ["windows-latest", "ubuntu-latest"], "node": [14, 16],
                        "include": [{"os": "windows-latest", "node": 16, "npm": 6}]})
    assert grid == [{"os": "windows-latest", "node": 14}, {"os": "windows-latest", "node": 16, "npm": 6},
                    {"os": "ubuntu-latest", "node": 14}, {"os": "ubuntu-latest", "node": 16}]


def test_docs_example_include_adds_to_every_combination():
    grid = expand_grid({"os": ["windows-latest", "ubuntu-latest"], "node": [14, 16],
                        "include": [{"node": 16, "npm": 6}]})
    assert [c.get("npm") for c in grid] == [None, 6, None, 6]


def test_docs_example_excluding_matrix_configurations():
    grid = expand_grid({"os": ["macos-latest", "windows-latest"], "version": [12, 14, 16],
                        "environment": ["staging", "production"],
                        "exclude": [{"os": "macos-latest", "version": 12, "environment": "production"},
                                    {"os": "windows-latest", "version": 16}]})
    assert len(grid) == 12 - 1 - 2
    assert {"os": "macos-latest", "version": 12, "environment": "production"} not in grid
    assert not [c for c in grid if c["os"] == "windows-latest" and c["version"] == 16]


def test_docs_example_include_only():
    grid = expand_grid({"include": [{"site": "production", "datacenter": "site-a"},
                                    {"site": "staging", "datacenter": "site-b"}]})
    assert grid == [{"site": "production", "datacenter": "site-a"}, {"site": "staging", "datacenter": "site-b"}]


def test_include_can_add_back_an_excluded_combination():
    grid = expand_grid({"a": [1, 2], "exclude": [{"a": 2}], "include": [{"a": 2, "x": True}]})
    assert grid == [{"a": 1}, {"a": 2, "x": True}]


def test_include_created_combinations_are_never_extended():
    grid = expand_grid({"a": [1], "include": [{"a": 2}, {"b": 3}]})
    assert grid == [{"a": 1, "b": 3}, {"a": 2}]


def test_exclude_matches_partially_on_object_values():
    grid = expand_grid({"cfg": [{"x": 1, "y": 2}, {"x": 3, "y": 4}], "exclude": [{"cfg": {"x": 1}}]})
    assert grid == [{"cfg": {"x": 3, "y": 4}}]


@pytest.mark.parametrize("mapping, message", [
    ({"a": []}, "at least one value"),
    ({"a": 3}, "is a list of values"),
    ({"a": [1], "exclude": [{"b": 1}]}, "not an axis"),
    ({"a": [1], "exclude": {"a": 1}}, "list of mappings"),
    ({"a": [1], "include": [3]}, "non-empty mapping"),
    ([1, 2], "expected a mapping"),
])
def test_malformed_matrices_raise_recipe_errors(mapping, message):
    with pytest.raises(RecipeError, match=message):
        expand_grid(mapping)


axes_strategy = st.dictionaries(st.sampled_from("abcde"), st.lists(st.integers(0, 4), min_size=1, max_size=3,
                                                                  unique=True), min_size=1, max_size=4)


@given(axes_strategy)
def test_base_product_has_no_duplicates_and_keeps_axis_order(axes):
    grid = expand_grid(axes)
    assert len(grid) == len({tuple(c.items()) for c in grid})
    assert grid == [dict(zip(axes, values)) for values in itertools.product(*axes.values())]
    assert all(list(c) == list(axes) for c in grid)


@given(axes_strategy, st.data())
def test_exclude_applies_before_include(axes, data):
    axis = data.draw(st.sampled_from(sorted(axes)))
    value = axes[axis][0]
    grid = expand_grid({**axes, "exclude": [{axis: value}], "include": [{axis: value, "extra": 1}]})
    # The include cannot extend the excluded combinations (they are gone), so it appears once, alone,
    # unless other combinations share nothing it would overwrite.
    assert {axis: value, "extra": 1} in grid
    assert all(c.get(axis) != value or c == {axis: value, "extra": 1} for c in grid)


# --- classes of alike values: planned once, standing for every cell -------------------------------------

def parity(axis, value):
    """A domain's `same`: on axis "a", values of one parity define the same thing."""
    return value % 2 if axis == "a" and isinstance(value, int) else None


def cells(grid):
    return sorted(map(repr, (sorted(cell.items()) for cell in grid.cells())))


def matrices():
    values = st.lists(st.integers(0, 5), min_size=1, max_size=5, unique=True)
    entry = st.dictionaries(st.sampled_from("abx"), st.integers(0, 5), min_size=1, max_size=2)
    return st.fixed_dictionaries({"a": values, "b": values},
                                 optional={"exclude": st.lists(entry.filter(lambda e: "x" not in e), max_size=3),
                                           "include": st.lists(entry, max_size=3)})


@given(matrices())
def test_classes_stand_for_exactly_the_cells_of_the_plain_grid(mapping):
    # GitHub Actions' semantics are kept: alike values multiplied back out give the plain grid's cells
    grid = expand_classes(mapping, parity)
    plain = expand_grid(mapping)
    assert cells(grid) == sorted(map(repr, (sorted(cell.items()) for cell in plain)))
    assert grid.count() == len(plain)
    assert len(grid.combinations) <= len(plain)


def test_alike_values_are_planned_once_and_named():
    grid = expand_classes({"a": [0, 1, 2, 3, 4], "b": ["x", "y"]}, parity)
    assert grid.combinations == [{"a": 0, "b": "x"}, {"a": 0, "b": "y"}, {"a": 1, "b": "x"}, {"a": 1, "b": "y"}]
    assert grid.count() == 10 and grid.same_as("a", 1) == [1, 3]
    assert describe_alike(grid) == "10 cells plan as 4 combinations: a 2, 4 as 0; 3 as 1"


def test_a_value_listed_twice_is_said_so():
    """Outside test: `strategy: [baseline, baseline]` read "2 cells plan as 1 combinations: strategy
    baseline as baseline"."""
    grid = expand_classes({"a": [0, 0]}, lambda axis, value: value)
    assert describe_alike(grid) == "2 cells plan as 1 combination: a 0 listed 2 times"
    grid = expand_classes({"a": [0, 2, 0]}, parity)
    assert describe_alike(grid) == "3 cells plan as 1 combination: a 2 as 0, 0 listed 2 times"


def test_a_value_an_entry_names_keeps_its_own_combinations():
    grid = expand_classes({"a": [0, 2, 4], "b": [1], "exclude": [{"a": 2}], "include": [{"a": 4, "z": 1}]}, parity)
    assert grid.combinations == [{"a": 0, "b": 1}, {"a": 4, "b": 1, "z": 1}]
    assert describe_alike(grid) is None


def test_a_million_alike_cells_are_a_few_combinations():
    grid = expand_classes({"a": list(range(0, 2_000_000, 2)), "b": [1, 2]}, parity)
    assert len(grid.combinations) == 2 and grid.count() == 2_000_000


def test_planning_is_bounded_by_distinct_combinations():
    with pytest.raises(RecipeError, match=r"the matrix makes 1,030,301 distinct combinations \(101 a × 101 b × "
                                          r"101 c\), more than 1,000,000 can be planned"):
        expand_grid({axis: list(range(101)) for axis in "abc"})
