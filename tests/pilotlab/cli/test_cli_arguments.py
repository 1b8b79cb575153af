"""`record` and `drive` refuse bad arguments at once, before any progress bar, and leave no --out."""
import time

import pytest

from pilotlab.cli import main


@pytest.mark.parametrize("argv, message", [
    (["record", "--circuit", "simple_circuit", "--laps", "nan"], "--laps: Input should be a finite number"),
    (["record", "--circuit", "simple_circuit", "--laps", "inf"], "--laps: Input should be a finite number"),
    (["record", "--circuit", "simple_circuit", "--start", "abc"], "--start: Input should be a valid number"),
    (["record", "--circuit", "simple_circuit", "--rate", "7"], "rate_hz must divide the control rate 20 Hz"),
    (["record", "--circuit", "simple_circuit", "--noise", "nan"], "--noise: Input should be a finite number"),
    (["drive", "--brain", "explicit", "--circuit", "simple_circuit", "--laps", "nan"], "--laps: Input should be a finite"),
    (["drive", "--brain", "explicit", "--circuit", "simple_circuit", "--timeout", "inf"], "--timeout: Input should be a finite"),
    (["drive", "--brain", "explicit", "--circuit", "nosuch"], "unknown circuit 'nosuch'"),
])
def test_bad_arguments_are_one_line_before_anything_starts(tmp_path, capsys, argv, message):
    out = tmp_path / ("run.bag" if argv[0] == "record" else "lap")
    started = time.monotonic()
    assert main(argv + ["--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert captured.err == f"pilotlab: error: {captured.err.removeprefix('pilotlab: error: ')}"
    assert message in captured.err and captured.err.count("\n") == 1
    assert captured.out == ""                      # no progress bar was drawn
    assert not out.exists() and time.monotonic() - started < 10


def test_a_command_s_parser_loads_its_own_module_and_help_lists_every_command(capsys):
    from pilotlab.cli import build_parser
    commands = lambda argv: set(build_parser(argv)._subparsers._group_actions[0].choices)
    assert commands(["-v", "plan", "r.yaml"]) == {"run", "plan", "status", "show", "gc"}
    assert commands(["circuit", "list"]) == {"circuit"}
    every = commands([])
    assert every == commands(["--help"]) == commands(["nosuch"])
    assert {"run", "plan", "record", "drive", "circuit", "dataset", "export", "report", "world"} <= every
    with pytest.raises(SystemExit):
        main(["nosuch"])
    err = capsys.readouterr().err
    assert "invalid choice: 'nosuch'" in err and "'record'" in err and "'plan'" in err
