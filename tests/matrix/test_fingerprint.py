"""Code fingerprints by module name: what a module builds on is read from its source, never imported."""
import json
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from matrix.fingerprint import clear_caches, closure_fingerprint, code_text, module_closure
from tests.child import python_path

ROOT = Path(__file__).resolve().parents[2]

PACKAGE = {
    "__init__.py": "",
    "strategy.py": ("import json\n"
                    "from shop.shared import helper\n"
                    "from shop.config import Settings\n"
                    "def run():\n"
                    "    import not_installed_heavy_library\n"
                    "    from shop.kernels import fast\n"
                    "    from shop import tables\n"),
    "kernels.py": "from . import maths\nraise RuntimeError('importing kernels would fail')\n",
    "maths.py": "",
    "tables.py": "import shop.maths\n",
    "config.py": "",
    "shared.py": "from shop import unrelated\n",
    "unrelated.py": "",
    "bystander.py": "",    # imported by nothing
}


@pytest.fixture
def shop(tmp_path, monkeypatch):
    """The package above on sys.path; afterwards forgotten (finding a module imports its package)."""
    (tmp_path / "shop").mkdir()
    for name, text in PACKAGE.items():
        (tmp_path / "shop" / name).write_text(text)
    monkeypatch.syspath_prepend(str(tmp_path))
    clear_caches()
    yield tmp_path / "shop"
    for name in [m for m in sys.modules if m == "shop" or m.startswith("shop.")]:
        del sys.modules[name]
    clear_caches()


def test_closure_follows_imports_inside_functions_without_importing(shop):
    closure = module_closure("shop.strategy", "shop", exclude=["shop.shared"])
    assert sorted(closure) == ["shop", "shop.config", "shop.kernels", "shop.maths", "shop.strategy", "shop.tables"]
    assert not {"shop.strategy", "shop.kernels", "not_installed_heavy_library"} & set(sys.modules)


def fingerprint_after(shop: Path, name: str, text: str) -> str:
    """The closure fingerprint of shop.strategy (as a job's key takes it) once `name` holds `text`."""
    (shop / name).write_text(text)
    clear_caches()
    return closure_fingerprint(module_closure("shop.strategy", "shop"))


def test_editing_a_module_in_the_closure_changes_the_fingerprint(shop):
    before = fingerprint_after(shop, "maths.py", "")
    assert fingerprint_after(shop, "bystander.py", "X = 1\n") == before   # not in the closure
    assert fingerprint_after(shop, "maths.py", "PI = 3.14\n") != before   # imported by a function's import, twice removed


def test_the_packages_above_a_module_are_its_code_too(shop):
    """Importing shop.sub.leaf runs shop/__init__.py and shop/sub/__init__.py first (pilotlab/sim's
    registers the Gymnasium environment): an edit there reruns what imports the leaf. What such a
    package imports is not followed (pilotlab/strategies/configs imports every strategy's config to
    register it: each strategy's jobs would become every strategy's)."""
    (shop / "sub").mkdir()
    (shop / "sub" / "__init__.py").write_text("from shop.sub import other\nREGISTRY = {}\n")
    (shop / "sub" / "other.py").write_text("")
    (shop / "sub" / "leaf.py").write_text("")
    (shop / "user.py").write_text("from shop.sub.leaf import thing\n")
    clear_caches()
    assert sorted(module_closure("shop.user", "shop")) == ["shop", "shop.sub", "shop.sub.leaf", "shop.user"]
    before = closure_fingerprint(module_closure("shop.user", "shop"))
    (shop / "sub" / "other.py").write_text("X = 1\n")
    clear_caches()
    assert closure_fingerprint(module_closure("shop.user", "shop")) == before
    for edited in (shop / "sub" / "__init__.py", shop / "__init__.py"):
        edited.write_text(edited.read_text() + "REGISTERED = True\n")
        clear_caches()
        after = closure_fingerprint(module_closure("shop.user", "shop"))
        assert after != before, edited
        before = after
    (shop / "user.py").write_text("from shop.sub.leaf import thing\nimport shop.sub\n")   # by name: followed
    clear_caches()
    assert "shop.sub.other" in module_closure("shop.user", "shop")


def test_comments_docstrings_and_blank_lines_are_not_code(shop):
    before = fingerprint_after(shop, "maths.py", '"""Maths."""\nPI = 3.14  # π\n')
    assert fingerprint_after(shop, "maths.py",
                             '"""Maths, reworded\nover two lines."""\n\n# a new comment\nPI = 3.14   # π, about\n') == before
    assert fingerprint_after(shop, "maths.py", '"""Maths."""\nPI = 3.1416\n') != before


def test_a_folder_without_init_above_a_job_s_module_runs_no_code(shop):
    """A job's module in a namespace package (a folder without `__init__.py`) below `within`: the
    folder is no code of the job (naming it failed: 'cannot find module 'shop.plain'')."""
    (shop / "plain").mkdir()
    (shop / "plain" / "leaf.py").write_text("from shop import maths\n")
    clear_caches()
    assert sorted(module_closure("shop.plain.leaf", "shop")) == ["shop", "shop.maths", "shop.plain.leaf"]
    assert closure_fingerprint(module_closure("shop.plain.leaf", "shop"))


def test_a_module_is_read_by_its_coding_line(shop):
    """A Latin-1 module (PEP 263 coding line) is code like any other: its comments are not code, its
    code is (it was read as UTF-8 and failed)."""
    def write(text: str):
        (shop / "maths.py").write_bytes(f"# -*- coding: latin-1 -*-\n{text}".encode("latin-1"))
        clear_caches()
        return closure_fingerprint(module_closure("shop.strategy", "shop"))
    before = write("NAME = 'café'  # é\n")
    assert write("NAME = 'café'  # è, reworded\n") == before
    assert write("NAME = 'cafè'\n") != before


@pytest.mark.parametrize("source, code", [
    ('def f(x):\n    """Doc."""\n    return x  # why\n', "def f(x):\n    return x"),
    ('class A:\n    """Doc\n    on two lines."""; B = 1\n', "class A:\n    ; B = 1"),
    ('s = "é"  # ü\nt = "# not a comment"\n', 's = "é"\nt = "# not a comment"'),
    ('def f():\n    x = 1\n    """not a docstring: not first"""\n', 'def f():\n    x = 1\n    """not a docstring: not first"""'),
    ("def broken(:\n    # kept whole\n", "def broken(:\n    # kept whole\n"),
    # rows as Python counts them: a line separator or a form feed in a comment moves no cut (review)
    ("# see\u2028here\nx = 123456789\ny = 2  # c\n", "x = 123456789\ny = 2"),
    ('x = 1\n\x0c\ndef f(a):\n    """doc\n    more"""\n    return a\n', "x = 1\ndef f(a):\n    return a"),
    # a multi-line string's spaces and blank lines are its value
    ('x = """a   \n\nb"""  # c\n', 'x = """a   \n\nb"""'),
    ("\ufeff# c\r\nx = 1\r\n", "x = 1"),
])
def test_code_text_drops_comments_and_docstrings_only(source, code):
    assert code_text(source) == code


CLOSURE_IN_A_PROCESS = ("from matrix.fingerprint import module_closure; "
                        "print(*module_closure('shop.strategy', 'shop', exclude=['shop.shared']))")


def closure_in_a_new_process(shop: Path, cache: Path) -> list[str]:
    env = {**os.environ, "MATRIX_HASH_CACHE": str(cache), "PYTHONPATH": python_path(ROOT, shop.parent)}
    return sorted(subprocess.run([sys.executable, "-c", CLOSURE_IN_A_PROCESS], env=env, check=True,
                                 capture_output=True, text=True).stdout.split())


def test_the_imports_read_are_remembered_across_processes_by_the_text(shop, tmp_path):
    cache = tmp_path / "hashes.sqlite"
    closure = closure_in_a_new_process(shop, cache)
    assert closure == ["shop", "shop.config", "shop.kernels", "shop.maths", "shop.strategy", "shop.tables"]
    # without the closure itself remembered, the next process believes the names the first one read
    # (proof that it parses no file again) ...
    with sqlite3.connect(cache) as db:
        db.execute("DELETE FROM closures")
        db.execute("UPDATE imports SET names = names || ' shop.unrelated'")
    assert closure_in_a_new_process(shop, cache) == sorted(closure + ["shop.unrelated"])
    # ... until a file's text changes
    for name in PACKAGE:
        (shop / name).write_text(PACKAGE[name] + "# edited\n")
    assert closure_in_a_new_process(shop, cache) == closure


def believed_closure(shop: Path, cache: Path) -> list[str]:
    """The closure a new process gives after the remembered one was tampered with (it names
    shop.unrelated): tampered, when the process believed the record."""
    with sqlite3.connect(cache) as db:
        for key, record in db.execute("SELECT key, record FROM closures").fetchall():
            record = json.loads(record)
            record["modules"] = [m for m in record["modules"] if m != "shop.unrelated"] + ["shop.unrelated"]
            db.execute("UPDATE closures SET record=? WHERE key=?", (json.dumps(record), key))
    return closure_in_a_new_process(shop, cache)


@pytest.mark.parametrize("edit", ["nothing", "a file's text", "a new module", "a module becomes a package",
                                  "a module removed"])
def test_a_closure_is_remembered_across_processes_while_what_it_was_read_from_holds(shop, tmp_path, edit):
    cache = tmp_path / "hashes.sqlite"
    closure = closure_in_a_new_process(shop, cache)
    if edit == "a file's text":
        (shop / "strategy.py").write_text(PACKAGE["strategy.py"].replace("    from shop import tables\n", ""))
        closure.remove("shop.tables")
    elif edit == "a new module":   # strategy.py imports the name shop.shared.helper: now a module
        (shop / "shared").mkdir()
        (shop / "shared" / "__init__.py").write_text("")
        (shop / "shared" / "helper.py").write_text("")
        (shop / "shared.py").unlink()
        closure = sorted(closure + ["shop.shared.helper"])
    elif edit == "a module becomes a package":
        (shop / "config.py").unlink()
        (shop / "config").mkdir()
        (shop / "config" / "__init__.py").write_text("from . import Settings\n")
        (shop / "config" / "Settings.py").write_text("")
        closure = sorted(closure + ["shop.config.Settings"])
    elif edit == "a module removed":   # strategy.py still names shop.tables: no longer a module
        (shop / "tables.py").unlink()
        closure.remove("shop.tables")
    tampered = sorted(closure + ["shop.unrelated"])
    assert believed_closure(shop, cache) == (tampered if edit == "nothing" else closure)


@pytest.mark.parametrize("damage", ["not json", "[]", '{"facts": {}}', '{"modules": ["shop.unrelated"]}'])
def test_a_damaged_closure_record_is_read_again(shop, tmp_path, damage):
    cache = tmp_path / "hashes.sqlite"
    closure = closure_in_a_new_process(shop, cache)
    with sqlite3.connect(cache) as db:
        db.execute("UPDATE closures SET record=?", (damage,))
    assert closure_in_a_new_process(shop, cache) == closure
