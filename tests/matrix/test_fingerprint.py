"""Code fingerprints by module name: what a module builds on is read from its source, never imported."""
import sys

import pytest

from matrix.fingerprint import clear_caches, code_fingerprint, module_closure

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
    assert sorted(closure) == ["shop.config", "shop.kernels", "shop.maths", "shop.strategy", "shop.tables"]
    assert not {"shop.strategy", "shop.kernels", "not_installed_heavy_library"} & set(sys.modules)


def test_editing_a_module_in_the_closure_changes_the_fingerprint(shop):
    before = code_fingerprint(module_closure("shop.strategy", "shop"))
    (shop / "maths.py").write_text("PI = 3.14\n")   # imported by a function's import, twice removed
    clear_caches()
    assert code_fingerprint(module_closure("shop.strategy", "shop")) != before
