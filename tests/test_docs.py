"""Every ```bash / ```sh / ```python block of README.md, docs/*.md and examples/*/README.md runs
as written.

The blocks of one file run in order in one temporary copy of the repository (so a later block
reuses what an earlier one wrote), ``sidprep`` being this checkout's CLI. They write into scratch
folders, never over a file the repository tracks: every tracked file of the copy is the same
after the blocks ran. A block that cannot run
in CI is opted out by the line ``<!-- docs-test: skip REASON -->`` right above its fence; the
reason is printed with the skip.
"""

import hashlib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md"), *(ROOT / "examples").glob("*/README.md")])
FENCE = re.compile(r"(?:<!-- docs-test: skip (?P<why>[^>]*?) -->\s*\n)?```(?P<lang>bash|sh|python)\n(?P<code>.*?)```",
                   re.S)
#: seconds one block may take (the slowest, the README tour, reduces two bundled meshes)
BLOCK_TIMEOUT_S = 300
#: the README's set-up block installs the package and runs the whole suite: that is CI itself
#: (.ci/run), so it is not run again from inside the suite
SET_UP = ("pip install", "installs sidprep and runs the test suite: CI (.ci/run) does exactly this")
#: what is copied into the temporary checkout (the files the docs use)
#: (the code itself runs from this checkout, with its compiled modules)
COPIED = ("data", "examples", "benchmarks", "docs", "README.md")


def blocks(path: Path) -> list[tuple[str, str, str | None]]:
    """(language, code, opt-out reason or None) of every runnable fence of ``path``."""
    out = [(m["lang"], m["code"], m["why"]) for m in FENCE.finditer(path.read_text())]
    return [(lang, code, SET_UP[1] if why is None and SET_UP[0] in code else why) for lang, code, why in out]


def checkout(tmp: Path) -> Path:
    for name in COPIED:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, tmp / name, ignore=shutil.ignore_patterns("__pycache__", "*.pvd", "*_vtu"))
        elif src.exists():
            shutil.copy2(src, tmp / name)
    bin_dir = tmp / ".bin"
    bin_dir.mkdir()
    shim = bin_dir / "sidprep"
    shim.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m sidprep.cli.main "$@"\n')
    shim.chmod(0o755)
    return tmp


def tracked_digests(copy: Path) -> dict[str, str]:
    """{path: sha256} of the files of ``copy`` that the repository tracks."""
    listed = subprocess.run(["git", "ls-files", *COPIED], cwd=ROOT, capture_output=True, text=True).stdout.split()
    return {name: hashlib.sha256((copy / name).read_bytes()).hexdigest() for name in listed
            if (copy / name).is_file()}


def run_block(lang: str, code: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PATH": f"{cwd / '.bin'}{os.pathsep}{os.environ['PATH']}",
           "MPLBACKEND": "Agg"}
    cmd = [sys.executable, "-c", code] if lang == "python" else ["bash", "-e", "-c", code]
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=BLOCK_TIMEOUT_S)


@pytest.mark.parametrize("doc", [d for d in DOCS if blocks(d)], ids=lambda d: str(d.relative_to(ROOT)))
def test_doc_blocks_run_as_written(doc, tmp_path):
    cwd = checkout(tmp_path)
    before = tracked_digests(cwd)
    failures, skipped = [], []
    for k, (lang, code, why) in enumerate(blocks(doc), 1):
        if why is not None:
            skipped.append(f"block {k}: {why}")
            continue
        run = run_block(lang, code, cwd)
        if run.returncode:
            failures.append(f"block {k} ({lang}) exit {run.returncode}:\n{code}\n{run.stderr[-1500:]}")
    for s in skipped:
        print(f"{doc.name} opt-out {s}")
    assert not failures, "\n\n".join(failures)
    after = tracked_digests(cwd)
    replaced = sorted(name for name, digest in before.items() if after.get(name) != digest)
    assert not replaced, f"the blocks wrote over tracked files (write into a scratch folder): {replaced}"


#: a dotted name of the package in the docs: ``sidprep.jobs.batch.read_study``
DOTTED = re.compile(r"\bsidprep(?:\.[a-z][a-z0-9_]*)+")         # public names (no leading _)
#: reached by attribute access after a plain ``import sidprep`` in a fresh interpreter
REACH = """
import sys, sidprep
for name in sys.argv[1:]:
    obj = sidprep
    for part in name.split(".")[1:]:
        obj = getattr(obj, part)
"""


def test_every_name_the_docs_use_is_reachable_after_import_sidprep():
    names = sorted({m.group() for doc in DOCS for m in DOTTED.finditer(doc.read_text())})
    assert len(names) > 40
    run = subprocess.run([sys.executable, "-c", REACH, *names], capture_output=True, text=True, cwd=ROOT,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert run.returncode == 0, run.stderr[-2000:]
