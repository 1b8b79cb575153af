"""`record` and `drive` refuse bad arguments at once, before any progress bar, and leave no --out."""
import time

import pytest

from pilotlab.cli import main


@pytest.mark.parametrize("argv, message", [
    (["record", "--circuit", "simple_circuit", "--laps", "nan"], "--laps: Input should be a finite number"),
    (["record", "--circuit", "simple_circuit", "--laps", "inf"], "--laps: Input should be a finite number"),
    (["record", "--circuit", "simple_circuit", "--start", "abc"], "--start: Input should be a valid number"),
    (["record", "--circuit", "simple_circuit", "--rate", "7"], "--rate must divide the control rate 20 Hz"),
    (["record", "--circuit", "simple_circuit", "--noise", "nan"], "--noise: Input should be a finite number"),
    (["drive", "--brain", "explicit", "--circuit", "simple_circuit", "--laps", "nan"], "--laps: Input should be a finite"),
    (["drive", "--brain", "explicit", "--circuit", "simple_circuit", "--timeout", "inf"], "--timeout: Input should be a finite"),
    (["drive", "--brain", "explicit", "--circuit", "nosuch"], "unknown circuit 'nosuch'"),
    # outside test: a path that names no file was told to give the path of a CSV
    (["drive", "--brain", "explicit", "--circuit", "data/nope.csv"], "circuit 'data/nope.csv': no such CSV file (looked for /"),
    (["record", "--circuit", "data/nope.csv"], "circuit 'data/nope.csv': no such CSV file (looked for /"),
    # outside test: a check across options read "options: fixed_inference_ms ... (got {'timing': 'lockstep', ..."
    (["drive", "--brain", "expert", "--circuit", "simple_circuit", "--timing", "lockstep", "--fixed-inference-ms", "80"],
     "pilotlab: error: --fixed-inference-ms only means something in the replay and measured timing modes, "
     "not 'lockstep'\n"),
    # outside test: in lockstep the search's every lap was completed (a tolerance of 1000 ms, never tested), and
    # the result said 100 ms had been added where nothing was
    (["drive", "--brain", "explicit", "--circuit", "simple_circuit", "--timing", "lockstep", "--tolerance"],
     "a latency tolerance search means nothing in the lockstep timing mode"),
    (["drive", "--brain", "brains/mine.py", "--circuit", "simple_circuit"],
     "--brain brains/mine.py: name the class in it too, as brains/mine.py:ClassName"),
    (["drive", "--brain", "explicit", "--circuit", "simple_circuit", "--timing", "lockstep", "--extra-latency-ms", "100"],
     "--extra-latency-ms means nothing in the lockstep timing mode (the world waits for the brain); use 'replay'"),
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


@pytest.mark.parametrize("argv, message", [
    # outside test: each ended in a traceback (a file where a folder goes, a format matplotlib lacks)
    (["circuit", "show", "simple_circuit", "-o", "{afile}/map.png"], "{afile}: File exists (FileExistsError)"),
    (["circuit", "show", "simple_circuit", "-o", "map.xyz"], "-o map.xyz: cannot write a .xyz image; give one of"),
    (["record", "--circuit", "simple_circuit", "--laps", "0.05", "--out", "{afile}/run"],
     "--out: {afile} is a file, so {afile}/run cannot be written below it"),
    (["record", "--circuit", "simple_circuit", "--laps", "0.05", "--out", "{afile}"], "--out: {afile} already exists"),
    # outside test: said after a progress line, and named a storage option `record` does not have
    (["record", "--circuit", "simple_circuit", "--format", "ros2", "--laps", "0.05", "--out", "run.bag"],
     "--out: run.bag: a ROS1 bag is a file ending in .bag and a ROS2 bag is a folder; rename the output, or write "
     "the other kind (`record --format`"),
    (["record", "--circuit", "simple_circuit", "--size", "0x0", "--out", "run"],
     "--size 0x0: width: Input should be greater than or equal to 16"),
    (["run", "{recipe}", "--store", "{afile}"], "--store {afile}: a file, not a store folder"),
    (["run", "{recipe}", "--executor", "dask", "--scheduler", "foo:bar"],
     "--scheduler foo:bar: not a Dask scheduler address"),
])
def test_an_output_path_that_cannot_be_made_is_one_line(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("mine\n")
    (tmp_path / "r.yaml").write_text("name: r\ndatasets:\n  train: {record: {circuits: [simple_circuit], laps: 0.1}}\n"
                                     "  test: {record: {circuits: [simple_circuit], laps: 0.1}}\n"
                                     "models:\n  m: {arch: pilotnet, epochs: 1}\nmatrix:\n  model: [m]\n"
                                     "  strategy: [baseline]\n  circuit: [simple_circuit]\n")
    names = {"afile": str(tmp_path / "afile"), "recipe": str(tmp_path / "r.yaml")}
    assert main([arg.format(**names) for arg in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("pilotlab: error: ") and err.count("\n") == 1 and message.format(**names) in err
    assert (tmp_path / "afile").read_text() == "mine\n"


def test_circuit_show_says_the_file_it_wrote(tmp_path, monkeypatch, capsys):
    """Outside test: `-o mymap` wrote mymap.png and said "map written to mymap"."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "maps").mkdir()
    assert main(["circuit", "show", "simple_circuit", "-o", "mymap"]) == 0
    assert main(["circuit", "show", "simple_circuit", "-o", "maps"]) == 0
    out = capsys.readouterr().out
    assert "map written to mymap.png" in out and f"map written to {'maps/simple_circuit.png'}" in out
    assert (tmp_path / "mymap.png").is_file() and (tmp_path / "maps" / "simple_circuit.png").is_file()


def test_circuit_list_shows_the_good_circuits_beside_a_bad_csv(tmp_path, monkeypatch, capsys):
    """Outside test: one bad CSV in ./circuits/ made `circuit list` fail as a whole."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "circuits").mkdir()
    (tmp_path / "circuits" / "bad.csv").write_text("x,y\n0,0\n1,0\n")
    assert main(["circuit", "list"]) == 1
    out = capsys.readouterr().out
    assert "simple_circuit" in out and "bad" in out and "cannot be driven:" in out and "bad.csv" in out


def test_a_reader_that_stops_early_ends_the_command_quietly(tmp_path):
    """Outside test: `pilotlab plan R | head -1` printed "code of yours called exit(1)" (rich's own exit
    on a broken pipe, taken for a user's). As Unix tools do, the program now ends quietly when the
    reader of its output has gone."""
    import fcntl
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[3]
    (tmp_path / "s").mkdir()                       # a store there (else plan notes on stderr that it is not)
    for args in (["plan", str(root / "recipes" / "study2022.yaml"), "--all", "--store", str(tmp_path / "s")],
                 ["plan", str(root / "recipes" / "study2022.yaml"), "--json", "--store", str(tmp_path / "s")]):
        child = subprocess.Popen([sys.executable, "-m", "pilotlab", *args], cwd=tmp_path, stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE)
        fcntl.fcntl(child.stdout.fileno(), 1031, 4096)   # F_SETPIPE_SZ: the plan (~25 KB) overflows the pipe
        child.stdout.readline()
        child.stdout.close()                       # as `head -1` does after its line
        assert child.wait(timeout=60) != 2 and child.stderr.read() == b""


@pytest.mark.parametrize("argv", [["-v", "circuit", "show", "nope_circ"], ["circuit", "show", "nope_circ", "-v"],
                                  ["circuit", "show", "--verbose", "nope_circ"]])
def test_verbose_is_taken_before_or_after_the_command(tmp_path, capsys, argv):
    """outside test: `pilotlab plan r.yaml -v` was refused (unrecognized arguments: -v)."""
    assert main(argv + ["-o", str(tmp_path / "m.png")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" in err and err.endswith("pilotlab: error: " + err.split("pilotlab: error: ")[-1])


def test_without_verbose_an_error_is_one_line(tmp_path, capsys):
    assert main(["circuit", "show", "nope_circ", "-o", str(tmp_path / "m.png")]) == 2
    assert capsys.readouterr().err.count("\n") == 1


@pytest.mark.parametrize("argv, usage", [(["plan", "r.yaml", "--bogus"], "usage: pilotlab plan "),
                                         (["circuit", "show", "simple_circuit", "--nope"], "usage: pilotlab circuit show ")])
def test_an_unknown_flag_is_said_with_its_command_s_usage(capsys, argv, usage):
    """outside test: a sub-command's unknown flag showed pilotlab's own usage (`pilotlab [-h] [-v] COMMAND ...`)."""
    with pytest.raises(SystemExit) as exited:
        main(argv)
    err = capsys.readouterr().err
    assert exited.value.code == 2 and err.startswith(usage) and f"unrecognized arguments: {argv[-1]}" in err


def test_a_run_stopped_by_sigterm_says_so_and_exits_143(monkeypatch, capsys):
    """Outside test: `kill PID` ended a run without a word of ours (matrix stops it as at Ctrl-C now,
    raising Terminated: tests/matrix/test_robustness.py)."""
    from matrix import cli as engine_cli
    from matrix.errors import Terminated

    def stopped(*_args, **_kwargs):
        raise Terminated()
    monkeypatch.setattr(engine_cli, "cmd_run", stopped)
    assert main(["run", "recipes/quickstart.yaml"]) == 143
    assert capsys.readouterr().err == ("pilotlab: terminated (SIGTERM): the jobs that finished are kept; run "
                                       "again to go on\n")


def test_a_run_stopped_by_ctrl_c_says_what_is_kept_as_at_sigterm(monkeypatch, capsys):
    """Outside test: Ctrl-C, the common stop, said only "pilotlab: interrupted"."""
    from matrix import cli as engine_cli

    def stopped(*_args, **_kwargs):
        raise KeyboardInterrupt()
    monkeypatch.setattr(engine_cli, "cmd_run", stopped)
    assert main(["run", "recipes/quickstart.yaml"]) == 130
    assert capsys.readouterr().err == "pilotlab: interrupted: the jobs that finished are kept; run again to go on\n"
    # outside test: on a Dask cluster the jobs already running went on, the message said nothing of them
    assert main(["run", "recipes/quickstart.yaml", "--executor", "dask", "--scheduler", "tcp://h:8786"]) == 130
    assert "the jobs already running on the Dask workers run to their end there" in capsys.readouterr().err
    monkeypatch.setattr(engine_cli, "cmd_plan", stopped)
    assert main(["plan", "recipes/quickstart.yaml"]) == 130
    assert capsys.readouterr().err == "pilotlab: interrupted\n"
