"""The command line's conventions: outputs in the current folder named by the input's
stem unless -o is given (README, "Where outputs go"); materials listed by --material list."""

import subprocess
import sys
from pathlib import Path

import pytest

from sidprep.cli.options import default_output, output_stem
from sidprep.fe.material import BUILTIN

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("name, stem", [("data/meshes/piston_rod.msh", "piston_rod"), ("a/b/rod.sid.h5", "rod"),
                                        ("scene.results.h5", "scene"), ("x/scene.toml", "scene"),
                                        ("run.h5", "run"), ("ROD.SID_FEM", "ROD")])
def test_output_stem(name, stem):
    assert output_stem(name) == stem
    assert default_output(name, ".html") == Path(stem + ".html")
    assert default_output(name, ".html", "out/page.html") == Path("out/page.html")


@pytest.mark.parametrize("command", [["beam"], ["reduce"], ["modes"]])
def test_material_list(command):
    r = subprocess.run([sys.executable, "-m", "sidprep.cli.main", *command, "--material", "list"],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    rows = {line.split()[0]: line.split()[1:] for line in r.stdout.splitlines()[1:-1]}
    assert set(rows) == set(BUILTIN)
    assert [float(x) for x in rows["steel"]] == [210.0, 0.3, 7850.0]


def test_view_writes_into_the_current_folder(tmp_path):
    r = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "view",
                        str(ROOT / "examples/flexible_pendulum/bar.sid.h5")], capture_output=True, text=True,
                       cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "bar.html").is_file() and r.stdout.strip() == "wrote bar.html"


#: the console command with an atexit handler of its own (it prints whether the cyclic garbage
#: collector runs), arguments from the command line
COMMAND = """
import atexit, gc, sys
atexit.register(lambda: print("atexit handler ran, collector", gc.isenabled()))
from sidprep.cli.main import command
sys.argv = ["sidprep", *sys.argv[1:]]
command()
"""
PENDULUM = ROOT / "examples" / "flexible_pendulum" / "scene.toml"


@pytest.mark.parametrize("argv, code, collector", [(["beam", "--material", "list"], 0, True),
                                                    (["info", "missing.sid.h5"], 2, True),
                                                    (["simulate", str(PENDULUM), "--list-signals"], 0, False)])
def test_the_command_ends_with_its_exit_code_its_output_and_the_atexit_handlers(tmp_path, argv, code, collector):
    """``command`` skips Python's module teardown (sidprep/cli/main.py): the exit code, everything written
    and the atexit handlers are kept; the sub-command's process set-up runs (simulate's pauses
    the cyclic garbage collector, sidprep/cli/options.py)."""
    r = subprocess.run([sys.executable, "-c", COMMAND, *argv], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == code, r.stderr
    assert r.stdout.endswith(f"atexit handler ran, collector {collector}\n")
    if argv[0] == "beam":
        assert "steel" in r.stdout
    elif argv[0] == "simulate":
        assert "hinge.coordinate" in r.stdout
    else:
        assert r.stderr.startswith("sidprep: error:") and "missing.sid.h5" in r.stderr
