"""``sidprep batch``: failure isolation, the content-addressed cache, resume after SIGKILL, Dask.

Independent references: an uninterrupted run's files (resume), the local pool's files (Dask), a
one-job ``sidprep reduce`` of the same mesh (batch output), the bar's first free-free frequency
from ``sidprep modes`` (a separate full-model eigen solve) within the reduction's check tolerance.
"""

import csv
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from readme_numbers import check_numbers

from sidprep.cli.main import main
from sidprep.jobs.batch import BatchOptions, jobs_from_meshes, read_study, run_batch
from sidprep.sid.io.sid_hdf5 import read_sid_hdf5
from sidprep.jobs.options import ReduceOptions

ROOT = Path(__file__).resolve().parents[1]
BAR = ROOT / "data" / "meshes" / "bar.msh"
#: few modes, no full-model frequency check: the batch machinery, not the reduction, is tested here
FAST = ["--modes", "2", "--no-check-frequencies", "--no-obj"]
#: relative tolerance of the reduced bar's first elastic frequency against the full FE model
FREQ_RTOL = 1e-3


def sid_arrays(path):
    s = read_sid_hdf5(path)
    return [s.mass, s.frequencies_hz, s.Me.M0, s.Ke.M0, s.Ct.M0, s.Cr.M0, s.J.M0]


def assert_same_sids(a: Path, b: Path, names):
    for n in names:
        for x, y in zip(sid_arrays(a / f"{n}.sid.h5"), sid_arrays(b / f"{n}.sid.h5")):
            np.testing.assert_array_equal(x, y)
        assert (a / f"{n}.SID_FEM").read_bytes() == (b / f"{n}.SID_FEM").read_bytes()


@pytest.fixture
def meshes(tmp_path):
    d = tmp_path / "in"
    d.mkdir()
    for name in ("bar_a", "bar_b", "bar_c"):
        shutil.copy(BAR, d / f"{name}.msh")
    (d / "corrupt.msh").write_text("$MeshFormat\n4.1 0 8\nthis is not a mesh\n")
    return d


def test_bundled_meshes_plus_a_corrupt_one_give_good_outputs_and_one_failure_then_the_cache(
        meshes, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["batch", str(meshes / "*.msh"), *FAST, "-o", str(out), "--workers", "2", "--json", "-q"]
    assert main(argv) == 1                                      # one job failed
    captured = capsys.readouterr()
    report = json.loads(captured.out)
    status = {r["name"]: r["status"] for r in report["jobs"]}
    assert status == {"bar_a": "ok", "bar_b": "ok", "bar_c": "ok", "corrupt": "failed"}
    failures = [line for line in captured.err.splitlines() if "failed" in line]
    assert len(failures) == 1 and "corrupt" in failures[0]
    # the batch's body equals a one-job reduce of the same mesh with the same options
    one = tmp_path / "one"
    assert main(["reduce", str(meshes / "bar_a.msh"), *FAST, "-o", str(one / "bar_a.sid.h5"), "-q"]) == 0
    capsys.readouterr()
    assert_same_sids(out, one, ["bar_a"])
    # the first elastic frequency agrees with a full-model eigen solve (sidprep modes)
    assert main(["modes", str(BAR), "--count", "1", "--json", "-q"]) == 0
    f_full = json.loads(capsys.readouterr().out)["frequencies_hz"][0]
    rec = next(r for r in report["jobs"] if r["name"] == "bar_a")
    assert rec["frequencies_hz"][0] == pytest.approx(f_full, rel=FREQ_RTOL)
    assert rec["dof"] == 3372 and rec["wall_s"] > 0 and rec["peak_memory_mb"] > 0
    table = json.loads((out / "batch.json").read_text())
    assert table["ok"] == 3 and table["failed"] == 1
    assert (out / "batch.csv").read_text().count("\n") == 5
    # the study's accuracy beside its cost and size: the FE checks' static and frequency errors, CPU-s, nq
    row = next(r for r in csv.DictReader(io.StringIO((out / "batch.csv").read_text())) if r["name"] == "bar_a")
    assert int(row["nq"]) == read_sid_hdf5(out / "bar_a.sid.h5").nq and float(row["cpu_s"]) > 0
    assert float(row["static_deflection_max_rel_error"]) == rec["checks"]["static_deflection_max_rel_error"]
    frequency = rec["checks"].get("eigen_frequency_max_rel_error")       # only when the run counts the spectrum
    assert row["eigen_frequency_max_rel_error"] == ("" if frequency is None else str(frequency))
    # re-run: served from the cache, says so, same exit code
    assert main(argv) == 1
    captured = capsys.readouterr()
    assert {r["name"]: r["status"] for r in json.loads(captured.out)["jobs"]}["bar_b"] == "cached"
    assert "3 of 4 job(s) served from the cache" in captured.err


def test_a_batch_killed_mid_way_resumes_to_the_outputs_of_an_uninterrupted_run(tmp_path):
    meshes = tmp_path / "in"
    meshes.mkdir()
    names = [f"bar{i}" for i in range(6)]
    for n in names:
        shutil.copy(BAR, meshes / f"{n}.msh")
    ref, killed = tmp_path / "ref", tmp_path / "killed"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "sidprep.cli.main", "batch", str(meshes / "*.msh"), *FAST, "--workers", "2", "-q"]
    proc = subprocess.Popen(cmd + ["-o", str(killed)], env=env, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and len(list((killed / ".cache").glob("*.json"))) < 2:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)                          # the driver and its pool
    proc.wait()
    done = len(list((killed / ".cache").glob("*.json")))
    assert 2 <= done < len(names), "the kill came too late to test a resume"
    for final in killed.glob("*.sid.h5"):                        # no half-written file under a final name
        sid_arrays(final)                                        # (a write cut short stays a hidden .part)
    resumed = subprocess.run(cmd + ["-o", str(killed), "--json"], env=env, capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr
    status = [r["status"] for r in json.loads(resumed.stdout)["jobs"]]
    assert status.count("cached") >= 2 and status.count("cached") + status.count("ok") == len(names)
    assert subprocess.run(cmd + ["-o", str(ref)], env=env).returncode == 0
    assert_same_sids(ref, killed, names)


def test_the_dask_path_gives_the_local_pool_results(tmp_path):
    distributed = pytest.importorskip("distributed")
    jobs = jobs_from_meshes([BAR], ReduceOptions(modes=2, check_frequencies=False))
    local = run_batch(jobs, BatchOptions(outdir=str(tmp_path / "local"), workers=1, obj=False))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as c, \
            distributed.Client(c) as client:
        remote = run_batch(jobs, BatchOptions(outdir=str(tmp_path / "dask"), obj=False), client=client)
    assert [r["status"] for r in remote.records] == ["ok"]
    assert remote.records[0]["frequencies_hz"] == local.records[0]["frequencies_hz"]
    assert_same_sids(tmp_path / "local", tmp_path / "dask", ["bar"])


def test_a_study_sweeps_the_cartesian_product_and_plots_frequencies(tmp_path):
    study = tmp_path / "study.toml"
    shutil.copy(BAR, tmp_path / "bar.msh")
    study.write_text('[job]\nmesh = "bar.msh"\ncheck_frequencies = false\nobj = false\n'
                     '[sweep]\nmodes = [2, 3]\nmaterial = ["steel", "aluminium"]\n[batch]\noutdir = "res"\n')
    jobs, settings = read_study(study)
    assert len(jobs) == 4 and settings["outdir"] == str(tmp_path / "res")
    assert sorted(j.name for j in jobs)[0] == "bar-modes=2-material=aluminium"
    assert settings["obj"] is False                                  # [job] obj = false is honoured
    report = run_batch(jobs, BatchOptions(**settings, workers=2))
    assert report.exit_code == 0 and Path(report.files["plot"]).is_file()     # f vs the numeric sweep (modes)
    assert not list((tmp_path / "res").glob("*.obj")) and len(list((tmp_path / "res").glob("*.SID_FEM"))) == 4
    f = {j.name: r["frequencies_hz"][0] for j, r in zip(jobs, report.records)}
    # same shape and nu: f scales exactly with sqrt(E / rho); EN 1999-1-1 aluminium E = 70 GPa, rho = 2700 kg/m^3,
    # EN 1993-1-1 steel 210 GPa, 7850 kg/m^3 (both nu = 0.3)
    ratio = f["bar-modes=2-material=aluminium"] / f["bar-modes=2-material=steel"]
    closed_form = np.sqrt((70e9 / 2700) / (210e9 / 7850))
    assert ratio == pytest.approx(closed_form, rel=1e-6)
    from sidprep.jobs.modal import modal_analysis
    from sidprep.jobs.options import ModalOptions

    full = modal_analysis(str(BAR), ModalOptions(count=1))
    steel = f["bar-modes=2-material=steel"]
    check_numbers(ROOT / "examples/reduce_job/README.md", "study", [
        steel, full.frequencies_hz[full.n_rigid], f["bar-modes=2-material=aluminium"], steel, closed_form])


@pytest.mark.parametrize("text, message", [
    ('[job]\nmesh = "bar.msh"\noutput = "x.sid.h5"\n', "set [batch] outdir"),
    ('[job]\nmesh = "bar.msh"\n[sweep]\nobj = [true, false]\n', "obj differs between the jobs"),
    ('[job]\nmesh = "bar.msh"\nsid_fem = false\n[batch]\nsid_fem = true\n', "keep one of them"),
])
def test_a_study_refuses_job_keys_it_cannot_honour(tmp_path, capsys, text, message):
    study = tmp_path / "s.toml"
    study.write_text(text)
    assert main(["batch", str(study)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and message in err and str(study) in err


def test_a_study_with_a_wrong_type_names_file_key_and_type(tmp_path, capsys):
    study = tmp_path / "s.toml"
    study.write_text('[job]\nmesh = "bar.msh"\n[sweep]\nmodes = ["six"]\n')
    assert main(["batch", str(study)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "s.toml" in err and "modes = 'six': expected an integer" in err


def test_jobs_start_only_while_their_memory_estimate_fits(tmp_path):
    from sidprep.jobs.batch import estimate_job_memory_mb

    meshes = []
    for i in range(3):
        shutil.copy(BAR, tmp_path / f"b{i}.msh")
        meshes.append(tmp_path / f"b{i}.msh")
    jobs = jobs_from_meshes(meshes, ReduceOptions(modes=2, check_frequencies=False))
    one_fits = 1.5 * estimate_job_memory_mb(3372)                # room for one bar job, not two
    report = run_batch(jobs, BatchOptions(outdir=str(tmp_path / "o"), workers=2, memory_limit_mb=one_fits, obj=False))
    spans = sorted((r["started_unix_s"], r["finished_unix_s"]) for r in report.records)
    assert report.exit_code == 0
    assert all(a_end <= b_start for (_, a_end), (b_start, _) in zip(spans, spans[1:]))   # never two at once


def test_the_summary_is_readable_at_80_columns():
    """Job names whole (folded, never cut to 'piston_...'); a static error above 1 % is a warning."""
    from rich.console import Console

    from sidprep.cli.batch import print_summary
    from sidprep.jobs.batch import BatchReport

    names = ["piston_rod-modes=8-material=aluminium-cutoff_factor=10", "bar-modes=2-material=steel"]
    records = [{"name": n, "status": "ok", "dof": 16374, "wall_s": 12.3, "peak_memory_mb": 812.0,
                "frequencies_hz": [262.1], "checks_passed": True,
                "checks": {"static_deflection_max_rel_error": e, "static_within_fembs_promise": e < 0.01}}
               for n, e in zip(names, (0.058, 0.0003))]
    console = Console(width=80, record=True)
    print_summary(BatchReport(records, "study_out", 30.0, {"json": "study_out/batch.json"}), console=console)
    text = console.export_text()
    assert max(len(line) for line in text.splitlines()) <= 80
    first_column = "".join(line.split("  ")[0].strip() for line in text.splitlines()[4:])
    assert all(n in first_column for n in names) and "…" not in text
    assert "warn 5.8 %" in text and "passed" in text


def kill_local_workers() -> None:
    """SIGKILL every spawned worker of this process, back once each is dead (a zombie, not reaped here)."""
    import psutil

    workers = [c for c in psutil.Process().children() if "spawn_main" in " ".join(c.cmdline())]
    for w in workers:
        w.kill()
    for w in workers:
        while w.is_running() and w.status() != psutil.STATUS_ZOMBIE:
            time.sleep(0.01)


def test_a_worker_killed_under_a_job_fails_that_job_alone_and_the_batch_goes_on(tmp_path):
    # SIGKILL of both local workers as the first job starts: that job fails as "worker lost", the
    # others run on workers started afresh (the killed ones are seen dead before a job is sent)
    jobs = jobs_from_meshes([BAR] * 3, ReduceOptions(modes=2, check_frequencies=False))
    jobs = [replace(job, name=f"bar{k}") for k, job in enumerate(jobs)]
    killed = []

    def progress(record, done, total, running):
        if running and not killed:
            kill_local_workers()
            killed.append(running[0])

    report = run_batch(jobs, BatchOptions(outdir=str(tmp_path), workers=2, obj=False), progress=progress)
    status = {r["name"]: r["status"] for r in report.records}
    assert status.pop(killed[0]) == "failed" and set(status.values()) == {"ok"}
    failed = next(r for r in report.records if r["name"] == killed[0])
    assert failed["error"].startswith("worker lost: BrokenProcessPool") and report.exit_code == 1


UNGUARDED = """import sidprep
jobs = sidprep.jobs.batch.jobs_from_meshes([{bar!r}], sidprep.ReduceOptions(modes=2))
report = sidprep.run_batch(jobs, sidprep.BatchOptions(outdir="out", workers=1))
"""


def test_run_batch_at_a_script_top_level_is_one_line_naming_the_main_guard(tmp_path):
    """Spawned workers import the script again: an unguarded call is refused before any worker
    starts (no lost workers, no lock message), with the fix in the one line."""
    script = tmp_path / "study.py"
    script.write_text(UNGUARDED.format(bar=str(BAR)))
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert r.returncode != 0
    last = r.stderr.strip().splitlines()[-1]
    assert f"{script}:3: run_batch runs at the top level of the script" in last
    assert 'if __name__ == "__main__":' in last and "BrokenProcessPool" not in r.stderr
    assert not (tmp_path / "out").exists()
