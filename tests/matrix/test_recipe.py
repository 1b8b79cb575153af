"""Recipe loading: typed validation, one-line errors with file:line and key path, did-you-mean."""
import string

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from matrix import MatrixError, RecipeError
from matrix.recipe import load_recipe
from tests.matrix.toydomain import TOY

GOOD = """\
name: toy
sources:
  a: {value: 2}
  b: {value: 3}
matrix:
  source: [a, b]
  power: [2, 3]
"""


def write(tmp_path, text):
    path = tmp_path / "recipe.yaml"
    path.write_text(text)
    return path


def error_of(tmp_path, text) -> str:
    with pytest.raises(RecipeError) as caught:
        load_recipe(write(tmp_path, text), TOY)
    message = str(caught.value)
    assert "\n" not in message
    return message


def test_a_good_recipe_loads_typed(tmp_path):
    recipe = load_recipe(write(tmp_path, GOOD), TOY)
    assert recipe.name == "toy"
    assert recipe.config.sources["a"].value == 2
    assert len(recipe.combinations) == 4


def test_bad_yaml_names_file_and_line(tmp_path):
    message = error_of(tmp_path, GOOD.replace("power: [2, 3]", "power: [2, 3"))
    assert message == (f"{tmp_path / 'recipe.yaml'}:7:10: not valid YAML: this [ list ] is not closed "
                       "(expected ',' or ']', but got '<stream end>' at line 8, column 1)")


@pytest.mark.parametrize("edit, message", [
    (("{value: 3}", "{value: 3"), ":4:6: not valid YAML: this { mapping } is not closed (expected ',' or '}', "
                                  "but got ':' at line 5, column 7)"),
    (("  b: {value: 3}", "  b: {value: 3}\n    c: 1"), ":5:5: not valid YAML: this line is indented differently from the lines around it"),
    # outside test: a bracket too many was said to be an indentation
    (("power: [2, 3]", "power: [2], 3]"), ":7:13: not valid YAML: a '}' or ']' before this closes more than was "
                                         "opened, or closes it too early"),
    (("name: toy", "name: \"toy"), ":1:7: not valid YAML: this quoted string is not closed"),
    (("name: toy", "name: t\x07oy"), ":1:8: not valid YAML: character U+0007 (a control character or a lone "
                                     "surrogate) is not allowed; remove it"),
    (("name: toy", "name: toy\x00"), ":1:10: not valid YAML: character U+0000"),
    (("matrix:", "matrix\n"), ":5:1: not valid YAML: this key has no ':' after it (could not find expected ':' at line 7"),
])
def test_yaml_syntax_errors_point_at_line_and_column(tmp_path, edit, message):
    assert error_of(tmp_path, GOOD.replace(*edit)).startswith(f"{tmp_path / 'recipe.yaml'}{message}")


def test_wrong_type_names_key_path_and_line(tmp_path):
    message = error_of(tmp_path, GOOD.replace("value: 3", "value: three"))
    assert message.endswith("valid integer, unable to parse string as an integer (got 'three')")
    assert ":4: sources.b.value:" in message


def test_unknown_key_suggests_the_closest(tmp_path):
    message = error_of(tmp_path, GOOD.replace("{value: 2}", "{valeu: 2}"))
    assert ":3: sources.a.valeu: unknown key 'valeu' (did you mean 'value'?)" in message


def test_unknown_top_level_section(tmp_path):
    message = error_of(tmp_path, GOOD + "sorces: {}\n")
    assert ":8: sorces: unknown key 'sorces' (did you mean 'sources'?)" in message


def test_missing_required_key(tmp_path):
    message = error_of(tmp_path, GOOD.replace("name: toy\n", ""))
    assert "missing required key 'name'" in message


def test_empty_axis(tmp_path):
    message = error_of(tmp_path, GOOD.replace("power: [2, 3]", "power: []"))
    assert ":7: matrix.power: an axis needs at least one value" in message


def test_exclude_naming_a_key_no_axis_has(tmp_path):
    message = error_of(tmp_path, GOOD + "  exclude:\n    - {source: a, pwer: 2}\n")
    assert ":9: matrix.exclude.0.pwer: exclude names 'pwer', which is not an axis (did you mean 'power'?)" in message


def test_combination_key_the_domain_does_not_know(tmp_path):
    message = error_of(tmp_path, GOOD + "  include:\n    - {colour: red}\n")
    assert ":9: matrix.include.0.colour: unknown axis 'colour'" in message


def test_axis_value_the_domain_does_not_know(tmp_path):
    message = error_of(tmp_path, GOOD.replace("source: [a, b]", "source: [a, bb]"))
    assert ":6: matrix.source.1: unknown source 'bb' (did you mean 'b'?); known: a, b" in message


def test_duplicate_keys_are_errors(tmp_path):
    message = error_of(tmp_path, GOOD + "name: again\n")
    assert ":8: duplicate key 'name'" in message


def test_everything_excluded(tmp_path):
    message = error_of(tmp_path, GOOD + "  exclude:\n    - {source: a}\n    - {source: b}\n")
    assert "no combinations left" in message


def test_an_empty_matrix_says_it_names_no_axis_not_that_exclude_removed_everything(tmp_path):
    """outside test: `matrix: {}` was blamed on an `exclude` the recipe did not have."""
    message = error_of(tmp_path, GOOD.split("matrix:")[0] + "matrix: {}\n")
    assert ":5: matrix: the matrix names no axis: give each axis a list of values" in message
    assert "exclude" not in message


def test_not_a_mapping(tmp_path):
    assert "a recipe is a mapping" in error_of(tmp_path, "- just\n- a list\n")


def test_missing_file(tmp_path):
    with pytest.raises(RecipeError, match="nope.yaml: no such file"):
        load_recipe(tmp_path / "nope.yaml", TOY)


# --- fuzzing: random YAML-like documents only ever raise the project's own exception -----------

scalars = st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True),
                    st.text(string.ascii_letters + " :-[]{}#&*!|>'\"%@`,?", max_size=8))
keys = st.sampled_from(["name", "sources", "matrix", "a", "b", "value", "sleep", "include", "exclude",
                        "source", "power", "description", "fail"])
documents = st.recursive(scalars, lambda children: st.one_of(
    st.lists(children, max_size=4), st.dictionaries(keys, children, max_size=5)), max_leaves=20)


@settings(max_examples=300, deadline=None)
@given(documents)
def test_random_documents_raise_only_matrix_errors(tmp_path_factory, document):
    path = tmp_path_factory.mktemp("fuzz") / "r.yaml"
    path.write_text(yaml.safe_dump(document))
    try:
        load_recipe(path, TOY)
    except MatrixError:
        pass


@settings(max_examples=300, deadline=None)
@given(st.text(string.printable, max_size=80))
def test_random_text_raises_only_matrix_errors(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("fuzz") / "r.yaml"
    path.write_text(text)
    try:
        load_recipe(path, TOY)
    except MatrixError:
        pass


@settings(max_examples=200, deadline=None)
@given(st.dictionaries(keys, documents, max_size=4), st.sampled_from(["name: x\n", GOOD]))
def test_random_sections_on_a_good_recipe(tmp_path_factory, extra, base):
    path = tmp_path_factory.mktemp("fuzz") / "r.yaml"
    path.write_text(base + yaml.safe_dump(extra))
    try:
        load_recipe(path, TOY)
    except MatrixError:
        pass


def test_identical_definitions_are_planned_once(tmp_path):
    import dataclasses

    from matrix import engine
    same = dataclasses.replace(TOY, same=lambda config, axis, value: config.sources.get(value) if axis == "source" else None)
    sources = [f"s{i}" for i in range(300)]
    text = ("name: alike\nsources:\n" + "".join(f"  {name}: {{value: 2}}\n" for name in sources) +
            "  other: {value: 3}\n" + f"matrix:\n  source: [{', '.join(sources)}, other]\n  power: [1, 2, 3]\n")
    recipe = load_recipe(write(tmp_path, text), same)
    assert recipe.grid.count() == 301 * 3 and len(recipe.combinations) == 2 * 3
    jobs = engine.plan_jobs(recipe, same)
    assert sorted(job.name for job in jobs) == ["power other^1", "power other^2", "power other^3", "power s0^1",
                                                "power s0^2", "power s0^3", "source other", "source s0", "total"]
    assert recipe.grid.same_as("source", "s0") == sources


def test_the_other_problems_are_named_where_they_are(tmp_path):
    """outside test: a typo'd top-level key ended '(and 1 more problem)' without saying which."""
    message = error_of(tmp_path, GOOD.replace("sources:", "sourcse:"))
    assert "unknown key 'sourcse' (did you mean 'sources'?)" in message
    assert message.endswith("(and 1 more problem: sources: missing required key 'sources')")


def test_a_value_where_a_mapping_goes_names_no_class(tmp_path):
    """outside test: 'Input should be a valid dictionary or instance of SourceSpec' named a class of ours."""
    message = error_of(tmp_path, GOOD.replace("a: {value: 2}", "a: two"))
    assert ":3: sources.a: 'a' should be a mapping of keys to values ({key: value, ...}) (got 'two')" in message
    assert "instance" not in message
