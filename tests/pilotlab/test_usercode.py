"""Loading code users write (file.py:Name, module:Name): the object, one-line errors naming the file
and line, and the source hash that goes into job keys."""
import shutil
import sys
import textwrap
from pathlib import Path

import pytest

from pilotlab.usercode import UserCodeError, base_of, load_object, source_files, source_hash, source_input

BRAIN = """
import numpy as np
from helpers import gain


class MyBrain:
    def act(self, image):
        return 5.0, gain() * float(np.mean(image))
"""


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text))
    return path


@pytest.fixture
def brains(tmp_path) -> Path:
    write(tmp_path, "brains/mine.py", BRAIN)
    write(tmp_path, "brains/helpers.py", "def gain():\n    return 0.0\n")
    write(tmp_path, "brains/unrelated.py", "X = 1\n")
    return tmp_path


def error_of(spec: str, base: Path) -> str:
    with pytest.raises(UserCodeError) as caught:
        load_object(spec, base)
    message = str(caught.value)
    assert "\n" not in message
    return message


def test_a_class_from_a_file_relative_to_base_imports_its_neighbours(brains):
    cls = load_object("brains/mine.py:MyBrain", brains)
    assert cls.__name__ == "MyBrain" and cls().act([1.0]) == (5.0, 0.0)
    assert load_object(str(brains / "brains/mine.py") + ":MyBrain", Path("/")).__name__ == "MyBrain"


def test_a_class_from_a_module(brains, monkeypatch):
    monkeypatch.setattr(sys, "path", list(sys.path))
    write(brains, "userpkg/__init__.py", "")
    write(brains, "userpkg/drivers.py", "class Slow:\n    class Inner:\n        pass\n")
    assert load_object("userpkg.drivers:Slow.Inner", brains).__qualname__ == "Slow.Inner"
    assert "no module 'userpkg.missing'" in error_of("userpkg.missing:Slow", brains)


def test_errors_name_the_file_and_line(brains):
    assert error_of("brains/none.py:MyBrain", brains).startswith("brains/none.py: no such file")
    write(brains, "brains/syntax.py", "class A:\n    def act(self image):\n        pass\n")
    message = error_of("brains/syntax.py:A", brains)
    assert message.startswith(f"{brains / 'brains/syntax.py'}:2: syntax error") and "def act(self image):" in message
    write(brains, "brains/imports.py", "import os\nimport no_such_module_here\n")
    message = error_of("brains/imports.py:A", brains)
    assert message.startswith(f"{brains / 'brains/imports.py'}:2: ModuleNotFoundError: No module named")
    write(brains, "brains/deep.py", "import failing\n")
    write(brains, "brains/failing.py", "x = 1\nraise RuntimeError('the helper is broken')\n")
    assert error_of("brains/deep.py:A", brains).startswith(
        f"{brains / 'brains/failing.py'}:2: RuntimeError: the helper is broken (importing brains/deep.py:A)")
    message = error_of("brains/mine.py:MyBrian", brains)
    assert "has no 'MyBrian' (did you mean 'MyBrain'?); it defines: MyBrain" in message
    assert "name user code as file.py:Class" in error_of("brains/mine.py", brains)


def test_a_module_that_parses_the_command_line_when_imported_sees_none_of_pilotlab_s(brains, monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["pilotlab", "drive", "--brain", "brains/args.py:A"])
    parse = "import argparse\nparser = argparse.ArgumentParser()\n{}\nARGS = parser.parse_args()\nclass A:\n    pass\n"
    write(brains, "brains/args.py", parse.format("parser.add_argument('--speed', type=float, default=3.0)"))
    assert load_object("brains/args.py:A", brains).__name__ == "A"    # its defaults: pilotlab's words are not its
    assert sys.argv[0] == "pilotlab"
    write(brains, "brains/needs.py", parse.format("parser.add_argument('model')"))
    message = error_of("brains/needs.py:A", brains)
    assert message == (f"{brains / 'brains/needs.py'}:4: the module called exit(2) while being imported (importing "
                       'brains/needs.py:A); put what runs it as a script under `if __name__ == "__main__":`')
    assert "needs.py: error: the following arguments are required: model" in capsys.readouterr().err


def test_the_source_hash_follows_the_file_and_its_local_imports(brains):
    spec = "brains/mine.py:MyBrain"
    assert [f.name for f in source_files(spec, brains)] == ["mine.py", "helpers.py"]   # not numpy, not unrelated.py
    first = source_hash(spec, brains)
    write(brains, "brains/unrelated.py", "X = 2\n")
    assert source_hash(spec, brains) == first
    write(brains, "brains/helpers.py", "def gain():\n    return 1.0\n")
    second = source_hash(spec, brains)
    write(brains, "brains/mine.py", BRAIN + "\n# a comment, reworded\n\n")
    assert source_hash(spec, brains) == second              # comments and blank lines are not code
    write(brains, "brains/mine.py", BRAIN + "\nLIMIT = 2\n")
    assert len({first, second, source_hash(spec, brains)}) == 3
    elsewhere = brains / "copy"
    for name in ("mine.py", "helpers.py"):
        write(elsewhere, f"brains/{name}", (brains / "brains" / name).read_text())
    assert source_hash(spec, elsewhere) == source_hash(spec, brains)   # the content counts, not the place


def test_a_latin_1_network_file_is_read_by_its_coding_line(brains):
    """Its imports are followed (they were not: it was parsed as UTF-8) and its comments are not code."""
    mine = brains / "brains" / "mine.py"
    mine.write_bytes(("# -*- coding: latin-1 -*-\n# café\n" + BRAIN).encode("latin-1"))
    spec = "brains/mine.py:MyBrain"
    assert [f.name for f in source_files(spec, brains)] == ["mine.py", "helpers.py"]
    first = source_hash(spec, brains)
    mine.write_bytes(("# -*- coding: latin-1 -*-\n# crème, reworded\n" + BRAIN).encode("latin-1"))
    assert source_hash(spec, brains) == first
    write(brains, "brains/helpers.py", "def gain():\n    return 1.0\n")
    assert source_hash(spec, brains) != first


@pytest.fixture(autouse=True)
def clean_imports(monkeypatch):
    """User modules (helpers, failing...) leave no trace in sys.path or sys.modules for other tests."""
    monkeypatch.setattr(sys, "path", list(sys.path))
    before = set(sys.modules)
    yield
    for name in set(sys.modules) - before:
        del sys.modules[name]


def test_a_module_of_a_package_with_relative_imports_loads_by_its_name_or_its_file(tmp_path, monkeypatch):
    """Outside test: `network: pkg.mine1:Net` whose module says `from .common import Base` failed in the
    job ("attempted relative import with no known parent package"): the job loads the file the spec
    names, which was loaded outside its package. A file in a package now imports as part of it."""
    monkeypatch.setattr(sys, "path", list(sys.path))
    package = f"relpkg_{tmp_path.name.replace('-', '_')}"        # unique: sys.modules is per process
    write(tmp_path, f"{package}/__init__.py", "")
    write(tmp_path, f"{package}/common.py", "class Base:\n    gain = 2.0\n")
    write(tmp_path, f"{package}/mine1.py", "from .common import Base\n\n\nclass Net(Base):\n    pass\n")
    by_name = load_object(f"{package}.mine1:Net", tmp_path)
    by_file = load_object(f"{tmp_path / package / 'mine1.py'}:Net", tmp_path / "elsewhere")
    assert by_file is by_name and by_file.gain == 2.0
    assert [f.name for f in source_files(f"{package}.mine1:Net", tmp_path)] == ["mine1.py", "__init__.py", "common.py"]


def test_the_source_hash_follows_imports_two_levels_up_and_through_the_top_package(tmp_path):
    """Outside test: a network in pkg/nets/net.py saying `from ..layers import Block` and `from pkg.scale
    import gain` loads (as part of its package) but neither file was in its source hash (relative imports
    deeper than one dot were left out, absolute ones were looked for beside the file only): editing them
    reran nothing."""
    write(tmp_path, "pkg/__init__.py", "")
    write(tmp_path, "pkg/nets/__init__.py", "")
    write(tmp_path, "pkg/layers.py", "class Block:\n    width = 8\n")
    write(tmp_path, "pkg/scale.py", "def gain():\n    return 2.0\n")
    write(tmp_path, "pkg/nets/net.py", "from ..layers import Block\nfrom pkg.scale import gain\n\n\n"
                                       "class Net(Block):\n    pass\n")
    spec = "pkg/nets/net.py:Net"
    assert {f.name for f in source_files(spec, tmp_path)} >= {"net.py", "layers.py", "scale.py"}
    first = source_hash(spec, tmp_path)
    write(tmp_path, "pkg/layers.py", "class Block:\n    width = 16\n")
    second = source_hash(spec, tmp_path)
    write(tmp_path, "pkg/scale.py", "def gain():\n    return 3.0\n")
    assert len({first, second, source_hash(spec, tmp_path)}) == 3
    assert load_object(f"{tmp_path / 'pkg' / 'nets' / 'net.py'}:Net", tmp_path).width == 16


def test_an_unreadable_module_the_file_imports_is_a_one_line_error(brains, monkeypatch):
    """Review: an OSError reading a module the file imports ended planning in a traceback."""
    helpers, read = (brains / "brains" / "helpers.py").resolve(), Path.read_bytes

    def refuse(path):
        if path == helpers:
            raise PermissionError(13, "Permission denied")
        return read(path)
    monkeypatch.setattr(Path, "read_bytes", refuse)
    with pytest.raises(UserCodeError, match="helpers.py: cannot read it"):
        source_hash("brains/mine.py:MyBrain", brains)


NET = """
import helpers


class Net:
    hidden = helpers.HIDDEN
"""


def test_two_folders_each_with_their_own_helpers_module_never_share_one(tmp_path, monkeypatch):
    """Outside test: a pool worker runs job after job; model b's `import helpers` got model a's helpers.py
    (already in sys.modules), so b trained with a's layer sizes and was stored under a key that names b's
    files. Loading from a folder now drops the modules imported from other user folders."""
    monkeypatch.setattr(sys, "path", list(sys.path))
    for folder, hidden in (("netsA", 8), ("netsB", 24)):
        write(tmp_path, f"{folder}/model.py", NET)
        write(tmp_path, f"{folder}/helpers.py", f"HIDDEN = {hidden}\n")
    hidden = [load_object(f"{folder}/model.py:Net", tmp_path).hidden for folder in ("netsA", "netsB", "netsA", "netsB")]
    assert hidden == [8, 24, 8, 24]
    assert sys.modules["helpers"].__file__ == str(tmp_path / "netsB" / "helpers.py")


def test_two_projects_each_with_a_package_of_the_same_name_load_their_own(tmp_path, monkeypatch):
    """Outside test: two projects, each with its package `nets/`: the second job in a worker failed with
    "another module 'nets.model' is loaded already", or not, by which worker took which job."""
    monkeypatch.setattr(sys, "path", list(sys.path))
    for project, gain in (("projA", 1.0), ("projB", 2.0)):
        write(tmp_path, f"{project}/nets/__init__.py", "")
        write(tmp_path, f"{project}/nets/common.py", f"GAIN = {gain}\n")
        write(tmp_path, f"{project}/nets/model.py", "from .common import GAIN\n\n\nclass Net:\n    gain = GAIN\n")
    gains = [load_object(f"{project}/nets/model.py:Net", tmp_path).gain for project in ("projA", "projB", "projA")]
    assert gains == [1.0, 2.0, 1.0]


@pytest.mark.parametrize("spec", ["brains/mine.py:MyBrain", "./brains/../brains/mine.py:MyBrain", "userpkg.drivers:Slow",
                                  "userpkg:Slow", "flat:Slow"])
def test_the_folder_a_spec_is_read_from_is_found_again_from_its_input_file(brains, spec):
    write(brains, "userpkg/__init__.py", "class Slow:\n    pass\n")
    write(brains, "userpkg/drivers.py", "class Slow:\n    pass\n")
    write(brains, "flat.py", "class Slow:\n    pass\n")
    moved = brains.with_name(brains.name + "_moved")
    shutil.copytree(brains, moved)
    file = Path(source_input(spec, moved).path)
    assert source_files(spec, base_of(spec, file)) == source_files(spec, moved)
    assert base_of(spec, file) == moved.resolve() or "/" in spec
