"""`pilotlab strategy list | show`: the strategies and their options, read from their configs (outside
test: no command listed them, and docs/strategies.md gives no option's default)."""
import dataclasses

from pilotlab.cli import main
from pilotlab.cli.strategy import options_of
from pilotlab.strategies import STRATEGIES


def test_list_names_every_strategy_with_its_options(capsys):
    assert main(["strategy", "list"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in STRATEGIES.names())
    assert "conv=0.3" in out and "the edge extra" in out


def test_show_gives_each_option_s_type_default_and_comment(capsys):
    assert main(["strategy", "show", "local_prune"]) == 0
    out = capsys.readouterr().out
    assert "conv" in out and "float" in out and "0.3" in out and "fraction of each conv layer" in out
    assert "checkpoint | torchscript | onnx" in out and "version" not in out
    assert main(["strategy", "show", "baseline"]) == 0
    assert capsys.readouterr().out == "baseline takes no options\n"


def test_every_field_of_every_config_is_an_option_shown():
    for name, entry in STRATEGIES.items():
        fields = [f.name for f in dataclasses.fields(entry.config_cls) if f.name != "version"]
        assert [option.name for option in options_of(entry.config_cls)] == fields, name
    inherited = {o.name: o.comment for o in options_of(STRATEGIES.get("pcqat_litert_int8").config_cls)}
    assert inherited["sparsity"] and inherited["clusters"]        # comments of the classes it builds on too


def test_an_unknown_strategy_says_which_it_may_be(capsys):
    assert main(["strategy", "show", "local_prun"]) == 2
    assert "unknown strategy 'local_prun' (did you mean 'local_prune'?)" in capsys.readouterr().err
