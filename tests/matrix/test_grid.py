"""expand_grid against the GitHub Actions documentation, plus properties."""
import itertools

import pytest
from hypothesis import given
from hypothesis import strategies as st

from matrix import RecipeError
from matrix.grid import expand_grid


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
