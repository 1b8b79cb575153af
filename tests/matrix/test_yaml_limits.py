"""Hostile YAML: nested aliases ("billion laughs"), merge-key bombs, self-reference, huge text."""
import sys
import time

import pytest

from matrix import yamlfile
from matrix.errors import RecipeError
from matrix.yamlfile import MAX_NESTING, MAX_VALUES, load_yaml


def laughs(levels: int = 9, width: int = 9) -> str:
    lines = [f"l0: &l0 [{', '.join(['lol'] * width)}]"]
    for n in range(1, levels):
        lines.append(f"l{n}: &l{n} [{', '.join([f'*l{n - 1}'] * width)}]")
    return "\n".join(lines) + "\n"


def merge_bomb(levels: int = 40) -> str:
    lines = ["m0: &m0 {x: 1}"]
    for n in range(1, levels):
        lines.append(f"m{n}: &m{n} {{<<: [*m{n - 1}, *m{n - 1}]}}")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("text", [laughs(), merge_bomb()], ids=["billion laughs", "merge keys"])
def test_nested_aliases_are_refused_at_once_with_one_line(text):
    started = time.monotonic()
    with pytest.raises(RecipeError) as error:
        load_yaml(text, "bomb.yaml")
    assert time.monotonic() - started < 2.0
    message = str(error.value)
    assert "aliases" in message and "bomb.yaml" in message and "\n" not in message


def test_aliases_within_the_bound_still_work():
    data, _ = load_yaml(laughs(levels=3, width=4))
    assert len(data["l2"]) == 4 and data["l2"][0][0] == ["lol"] * 4
    assert MAX_VALUES >= 10_000


def test_an_alias_to_itself_is_one_line():
    with pytest.raises(RecipeError, match="refers to itself"):
        load_yaml("a: &a\n  b: *a\n")


@pytest.fixture(params=[None, 20_000], ids=["default recursion limit", "raised recursion limit"])
def recursion_limit(request):
    before = sys.getrecursionlimit()
    sys.setrecursionlimit(request.param or before)
    yield
    sys.setrecursionlimit(before)


@pytest.mark.parametrize("fast", [True, False], ids=["libyaml", "pyyaml"])
def test_deep_nesting_is_refused_whatever_the_recursion_limit(fast, recursion_limit, monkeypatch):
    """The bound is ours: a library raising the interpreter's recursion limit (something in the test run
    does) must not change the answer; with a raised limit PyYAML's own parser read 1500 levels and the
    document was taken."""
    if not fast:
        monkeypatch.setattr(yamlfile, "FAST_LOADER", None)
    for depth in (MAX_NESTING + 1, 1500):
        with pytest.raises(RecipeError, match=f"nested deeper than {MAX_NESTING} levels"):
            load_yaml("a: " + "[" * depth + "]" * depth + "\n")
    data, _ = load_yaml("a: " + "[" * (MAX_NESTING - 1) + "]" * (MAX_NESTING - 1) + "\n")
    levels, value = 0, data["a"]
    while value:
        levels, value = levels + 1, value[0]
    assert levels == MAX_NESTING - 2     # the innermost [] is empty


def test_a_huge_document_is_refused_before_parsing():
    started = time.monotonic()
    with pytest.raises(RecipeError, match="too large for a recipe"):
        load_yaml("x: " + "a" * (5 * 2**20))
    assert time.monotonic() - started < 2.0


def test_a_missing_recipe_suggests_the_ones_nearby(tmp_path, monkeypatch):
    from matrix.yamlfile import read_yaml
    (tmp_path / "recipes").mkdir()
    for name in ("quickstart.yaml", "study2022.yaml"):
        (tmp_path / "recipes" / name).write_text("name: x\n")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(RecipeError, match=r"no such file; did you mean recipes/quickstart.yaml\?"):
        read_yaml("quickstrat.yaml")
    with pytest.raises(RecipeError, match=r"did you mean recipes/study2022.yaml\?"):
        read_yaml("recipes/studdy2022.yaml")
    with pytest.raises(RecipeError, match="recipes nearby: recipes/quickstart.yaml, recipes/study2022.yaml"):
        read_yaml("zzz.yaml")
    (tmp_path / "empty").mkdir()
    monkeypatch.chdir(tmp_path / "empty")
    with pytest.raises(RecipeError, match=r"no such file$"):
        read_yaml(str(tmp_path / "nowhere" / "x.yaml"))


REJECTED = {"an unclosed mapping": "a: {b: 1\nc: 2\n", "a bad indent": "a:\n  b: 1\n c: 2\n",
            "deep nesting": "a: " + "[" * 1500 + "]" * 1500 + "\n", "a lone surrogate": 'a: "\ud800"\n',
            "a control character": "a: 1\x07\n"}


@pytest.mark.parametrize("text", REJECTED.values(), ids=REJECTED)
def test_libyaml_and_pyyaml_refuse_a_document_in_the_same_words(text, monkeypatch):
    """libyaml parses (where PyYAML has it); what it rejects is read again by PyYAML's own parser, so the
    one-line error is the same either way."""
    with pytest.raises(RecipeError) as fast:
        load_yaml(text, "r.yaml")
    monkeypatch.setattr(yamlfile, "FAST_LOADER", None)
    with pytest.raises(RecipeError) as slow:
        load_yaml(text, "r.yaml")
    assert str(fast.value) == str(slow.value) and "\n" not in str(fast.value)


DOCUMENT = """
name: every style   # a comment
description: >
  folded text
  over lines
base: &base {epochs: 2, lr: 1e-3, flags: [yes, no, ~, 0x10, 1_000, .inf, 2001-12-14]}
models:
  a: {<<: *base, seed: 3}
  b:
    <<: *base
    note: 'single ''quoted'''
    text: "double\\tescaped"
    block: |
      kept
      lines
matrix:
  - [1, 2.5, -3]
  - {x: null, "quoted key": true}
"""


def test_both_parsers_read_a_document_alike(monkeypatch):
    fast = load_yaml(DOCUMENT, "r.yaml")
    monkeypatch.setattr(yamlfile, "FAST_LOADER", None)
    assert load_yaml(DOCUMENT, "r.yaml") == fast
    assert fast[0]["models"]["a"]["epochs"] == 2 and fast[1][("models", "b", "block")] == 13


def test_a_key_written_beside_a_merge_overrides_the_merged_one_and_duplicates_stay_errors():
    """Outside test: `m2: {<<: *m, epochs: 1}` where *m has epochs was refused as a duplicate key;
    YAML's merge lets the key written there override the merged one. Two written keys are an error."""
    text = "m: &m {arch: a, epochs: 5, lr: 1}\nm2: {<<: *m, epochs: 1, lr: 2}\nm3:\n  <<: [*m]\n  epochs: 7\n"
    data, lines = load_yaml(text, "r.yaml")
    assert data["m2"] == {"arch": "a", "epochs": 1, "lr": 2} and data["m3"]["epochs"] == 7
    assert lines[("m2", "epochs")] == 2
    with pytest.raises(RecipeError, match=r"r.yaml:2: m2: duplicate key 'epochs'"):
        load_yaml("m: &m {arch: a}\nm2: {<<: *m, epochs: 1, epochs: 2}\n", "r.yaml")
