"""Where the report goes: a folder that cannot be written is a one-line error; the report is written
beside the old one and swapped in, so two writers at once both succeed and leave one whole report."""
import subprocess
import sys
from pathlib import Path

from matrix.engine import make_plan
from matrix.recipe import load_recipe
from matrix.store import Store
from pilotlab.cli import main
from pilotlab.domain import DOMAIN

ROOT = Path(__file__).resolve().parents[3]
QUICKSTART = ROOT / "recipes" / "quickstart.yaml"


def recipe_with_a_result(tmp_path, folder) -> tuple[Path, Path]:
    """The quickstart recipe writing its report to `folder`, and a store holding one failed job."""
    recipe = tmp_path / "quickstart.yaml"
    recipe.write_text(QUICKSTART.read_text() + f"\nreport: {{folder: {folder}}}\n")
    store = Store(tmp_path / "store")
    train = next(s.job for s in make_plan(load_recipe(recipe, DOMAIN), DOMAIN, store).statuses if s.job.kind == "train")
    store.record_failure(train.key, {"error": "RuntimeError: loss is nan"})
    return recipe, store.root


def test_a_report_folder_that_cannot_be_written_is_one_line(tmp_path, capsys):
    for folder in ("/dev/null", "/proc/version/x"):
        recipe, store = recipe_with_a_result(tmp_path, folder)
        assert main(["report", str(recipe), "--store", str(store)]) == 2
        err = capsys.readouterr().err
        assert "report.folder" in err and "cannot write" in err and len(err.strip().splitlines()) == 1


def test_two_writers_of_one_report_both_succeed_and_leave_one_whole_report(tmp_path):
    recipe, store = recipe_with_a_result(tmp_path, tmp_path / "reports")
    command = [sys.executable, "-m", "pilotlab", "report", str(recipe), "--store", str(store)]
    writers = [subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
               for _ in range(2)]
    for writer in writers:
        out, err = writer.communicate(timeout=300)
        assert writer.returncode == 0, err
    folder = tmp_path / "reports" / "quickstart"
    assert {p.name for p in folder.iterdir()} >= {"README.md", "index.html", "results.csv", "plots", ".stamp"}
    assert [p.name for p in folder.parent.iterdir() if p.name.startswith(".quickstart.") and
            not p.name.endswith(".lock")] == []
    assert "not run yet" in (folder / "README.md").read_text() or "failed" in (folder / "README.md").read_text()


def test_a_run_writes_where_git_ignores_and_showcases_live_elsewhere():
    """Running the quickstart in a clone must not turn it dirty: reports/ is ignored, the committed
    showcase reports live in docs/reports/, which no recipe writes."""
    import shutil

    import pytest
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    from pilotlab.report.recipe import report_folder
    folder = report_folder(load_recipe(QUICKSTART, DOMAIN))
    assert folder == Path("reports") / "quickstart"
    ignored = subprocess.run(["git", "check-ignore", "-q", str(folder / "README.md")], cwd=ROOT)
    assert ignored.returncode == 0
    assert (ROOT / "docs" / "reports" / "quickstart" / "README.md").is_file()


def test_a_report_replaces_only_a_report_never_a_folder_or_file_of_yours(tmp_path, capsys):
    """Outside test: a recipe named like a folder of the user's (`name: src`, `report: {folder: .}`)
    had its report swapped in over that folder, deleting it. Now it is refused with one line, and the
    folder and file stay; an empty folder or an earlier report is replaced as before."""
    recipe, store = recipe_with_a_result(tmp_path, tmp_path / "out")
    mine = tmp_path / "out" / "quickstart"
    (mine / "src").mkdir(parents=True)
    (mine / "src" / "main.py").write_text("print(1)\n")
    assert main(["report", str(recipe), "--store", str(store)]) == 2
    err = capsys.readouterr().err
    assert "not a pilotlab report" in err and "another name or report.folder" in err and len(err.splitlines()) == 1
    assert f"error: {recipe}:" in err and ": report.folder: " in err   # outside test: it had no file:line
    assert (mine / "src" / "main.py").read_text() == "print(1)\n"
    (mine / "src" / "main.py").unlink()
    (mine / "src").rmdir()
    mine.rmdir()
    mine.write_text("my thesis\n")                       # a file where the report folder would go
    assert main(["report", str(recipe), "--store", str(store)]) == 2
    assert "is not a folder" in capsys.readouterr().err and mine.read_text() == "my thesis\n"
    mine.unlink()
    mine.mkdir()                                         # an empty folder: taken
    assert main(["report", str(recipe), "--store", str(store)]) == 0
    assert main(["report", str(recipe), "--store", str(store)]) == 0   # its own report: replaced
    assert (mine / ".stamp").is_file() and (mine / "README.md").is_file()


def test_a_report_never_replaces_the_report_of_another_recipe_named_alike(tmp_path, capsys):
    """Outside test: `name: my recipe` and `name: my_recipe` make one folder name (my_recipe), and each
    run overwrote the other's report. Now the second is refused with one line naming both recipes; a
    stamp from before the recipe's name was kept in it is a report all the same, and replaced."""
    recipe, store = recipe_with_a_result(tmp_path, tmp_path / "out")
    text = recipe.read_text()
    recipe.write_text(text.replace("name: quickstart", "name: my recipe", 1))
    assert main(["report", str(recipe), "--store", str(store)]) == 0
    folder = tmp_path / "out" / "my_recipe"
    readme = (folder / "README.md").read_text()
    recipe.write_text(text.replace("name: quickstart", "name: my_recipe", 1))
    assert main(["report", str(recipe), "--store", str(store)]) == 2
    err = capsys.readouterr().err
    assert "'my recipe'" in err and "'my_recipe'" in err and "another name or report.folder" in err
    assert len(err.splitlines()) == 1 and (folder / "README.md").read_text() == readme
    (folder / ".stamp").write_text('"0123abcd"')          # the stamp of an older pilotlab: no recipe name
    assert main(["report", str(recipe), "--store", str(store)]) == 0
    assert "my_recipe" in (folder / "README.md").read_text()


def test_files_of_yours_in_a_report_folder_are_kept_when_the_report_is_rewritten(tmp_path, capsys):
    """Outside test: notes put beside a report were deleted, silently, by the next `report` or `run`."""
    recipe, store = recipe_with_a_result(tmp_path, tmp_path / "out")
    assert main(["report", str(recipe), "--store", str(store)]) == 0
    folder = tmp_path / "out" / "quickstart"
    (folder / "notes.txt").write_text("mine\n")
    (folder / "mine").mkdir()
    (folder / "mine" / "draft.md").write_text("draft\n")
    (folder / "README.md").write_text("edited")              # a file the report writes stays the report's
    assert main(["report", str(recipe), "--store", str(store)]) == 0
    assert (folder / "notes.txt").read_text() == "mine\n" and (folder / "mine" / "draft.md").read_text() == "draft\n"
    assert (folder / "README.md").read_text() != "edited"
    assert main(["report", str(recipe), "--store", str(store)]) == 0   # and again, from the new report's list
    assert (folder / "notes.txt").is_file()


def test_a_report_folder_under_home_is_expanded(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    recipe, store = recipe_with_a_result(tmp_path, "~/reports")
    monkeypatch.chdir(tmp_path)
    assert main(["report", str(recipe), "--store", str(store)]) == 0
    assert (tmp_path / "home" / "reports" / "quickstart" / "README.md").is_file() and not (tmp_path / "~").exists()
