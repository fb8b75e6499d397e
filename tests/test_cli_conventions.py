"""The command line's conventions (issue 27): outputs in the current folder named by the input's
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
