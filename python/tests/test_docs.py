"""Every command and code block of the README and the site, run.

Each page's ```bash and ```python blocks run in order in a directory of their
own, where `reeb` is the binary under test and `scenes/` holds the shipped
scenes at a small size (every axis at most 6 values, every random ensemble at
most 64 orbits, at most 400 steps), so a page's commands run as a user types
them, in seconds. A ```bash line that is one of CI's own steps (the test
suite, the site's build) is checked to be one, word for word, in `.ci/run`.
A block that cannot run here says why in a `<!-- not run: REASON -->` line
just above it; those are listed by `test_blocks_not_run_say_why`.
Synopses and output are ```text. A ```toml block is TOML, and one that is a
whole scene (a model and an integrator) passes `reeb check` at small size.
"""

import os
import re
import shutil
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md"] + sorted(
    p for p in (ROOT / "docs").glob("*.md") if p.name != "index.md"  # index.md is the README
)
BLOCK = re.compile(r"^(?:<!-- not run: (?P<why>.+?) -->\n)?```(?P<lang>\w*)\n(?P<body>.*?)^```", re.S | re.M)
SMALL_AXIS, SMALL_RANDOM, SMALL_STEPS = 6, 64, 400


def blocks(page: Path):
    """(language, body, reason not run or None) of each fenced block."""
    return [(m["lang"], m["body"], m["why"]) for m in BLOCK.finditer(page.read_text())]


def reeb_bin() -> Path:
    path = os.environ.get("REEB_BIN")
    if not path:
        pytest.skip("REEB_BIN not set (CI sets it to target/release/reeb)")
    return Path(path)


def small_scene(text: str) -> str:
    """A scene's text with its axes, random ensembles and steps capped."""
    text = re.sub(
        r"((?:linspace|logspace) = \[[^,\]]+,[^,\]]+,\s*)(\d+)",
        lambda m: m[1] + str(min(int(m[2]), SMALL_AXIS)),
        text,
    )
    text = re.sub(
        r"(random = \{[^}]*\bn = )(\d+)", lambda m: m[1] + str(min(int(m[2]), SMALL_RANDOM)), text
    )
    return re.sub(r"(?m)^(steps = )(\d+)", lambda m: m[1] + str(min(int(m[2]), SMALL_STEPS)), text)


def workdir(tmp: Path, reeb: Path) -> dict:
    """A directory with the small scenes and `reeb` on the PATH; its environment."""
    (tmp / "scenes").mkdir()
    for scene in (ROOT / "scenes").glob("*.toml"):
        (tmp / "scenes" / scene.name).write_text(small_scene(scene.read_text()))
    bin_dir = tmp / ".bin"
    bin_dir.mkdir()
    (bin_dir / "reeb").symlink_to(reeb)
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    env["MPLBACKEND"] = "Agg"
    return env


def ci_steps() -> set:
    return {line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()}


def small_command(line: str, tmp: Path) -> str:
    """The line as it runs here: the built binary, small sizes, this machine."""
    line = line.replace("cargo run --release -- ", "reeb ")
    line = re.sub(r"--repeats \d+", "--repeats 1", line)
    if line.startswith("reeb bench"):
        line = re.sub(r"--(n|steps|threads|precision) \S+", "", line)
        line += " --steps 20" if "--indicators" in line else " --n 2000 --steps 20 --threads 1 --precision f32"
    if line.startswith("reeb doctor"):
        # One adapter and small ensembles: what any CI machine has.
        line = re.sub(r"--adapter \d+", "--adapter 0", line)
        line = re.sub(r"--n [\d,]+", "", line) + " --n 1000 --skip-verify"
    if line.startswith("reeb slurm"):
        # The CI's one-node cluster has one partition and no GPUs.
        line = re.sub(r"--partition \S+|--gpus-per-task \S+", "", line)
        if shutil.which("sbatch") is None:
            if os.environ.get("REEB_REQUIRE_SLURM"):
                pytest.fail("REEB_REQUIRE_SLURM is set but sbatch is not on the PATH")
            line += " --dry-run"
    return line.replace("/scratch/", f"{tmp}/scratch/")


def run_bash(body: str, tmp: Path, env: dict, steps: set, where: str) -> None:
    lines = []
    for line in body.splitlines():
        command = re.sub(r"\s+#.*$", "", line).strip()
        if not command or command.startswith("#"):
            continue
        if command.startswith(("cargo test", "scripts/build_docs.sh")):
            assert any(command in step for step in steps), f"{where}: `{command}` is not a step of .ci/run"
            continue
        lines.append(small_command(command, tmp))
    if not lines:
        return
    script = "set -euo pipefail\n" + "\n".join(lines) + "\n"
    done = subprocess.run(["bash", "-c", script], cwd=tmp, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"{where}:\n{script}\nstdout:\n{done.stdout[-3000:]}\nstderr:\n{done.stderr[-3000:]}"


def wait_for_slurm(tmp: Path) -> None:
    """Slurm jobs the page submitted, run to their end: the merged run's
    summary.json is there."""
    if shutil.which("sbatch") is None or not (tmp / "scratch").exists():
        return
    for _ in range(600):
        queue = subprocess.run(["squeue", "-h"], capture_output=True, text=True)
        if not queue.stdout.strip():
            break
        time.sleep(0.5)
    else:
        pytest.fail("the page's Slurm jobs did not finish within 300 s")
    runs = [d for d in (tmp / "scratch").iterdir() if (d / "summary.json").exists()]
    assert runs, f"the Slurm jobs left no finished run in {tmp / 'scratch'}: {sorted(os.listdir(tmp / 'scratch'))}"


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_every_block_of_the_page_runs(page: Path, tmp_path: Path):
    runnable = [(lang, body) for lang, body, why in blocks(page) if why is None and lang in ("bash", "python")]
    if not runnable:
        return
    reeb = reeb_bin()
    env = workdir(tmp_path, reeb)
    steps = ci_steps()
    for k, (lang, body) in enumerate(runnable):
        where = f"{page.name}, block {k + 1} ({lang})"
        if lang == "bash":
            run_bash(body, tmp_path, env, steps, where)
            wait_for_slurm(tmp_path)
        else:
            done = subprocess.run(
                [sys.executable, "-c", body], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
            )
            assert done.returncode == 0, f"{where}:\n{body}\n{done.stderr[-3000:]}"


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_every_scene_of_the_page_is_one_reeb_accepts(page: Path, tmp_path: Path):
    scenes = [body for lang, body, _ in blocks(page) if lang == "toml"]
    for k, body in enumerate(scenes):
        where = f"{page.name}, TOML block {k + 1}"
        table = tomllib.loads(body)  # a fragment is TOML too
        if not {"model", "integrator"} <= table.keys():
            continue
        scene = tmp_path / f"scene{k}.toml"
        scene.write_text(small_scene(body))
        done = subprocess.run([str(reeb_bin()), "check", str(scene)], capture_output=True, text=True)
        assert done.returncode == 0, f"{where}: {done.stderr}"


def test_blocks_not_run_say_why():
    """A block left unrun names its reason; a command is never untagged."""
    for page in PAGES:
        for lang, body, why in blocks(page):
            if why is not None:
                assert lang == "bash", f"{page.name}: only commands may be marked not run"
                print(f"{page.name}: not run ({why}): {body.splitlines()[0]}")
            assert lang != "", f"{page.name}: a block without a language: {body[:60]!r}"


def test_the_python_api_page_names_every_public_name():
    import reeb

    page = (ROOT / "docs" / "python-api.md").read_text()
    documented = set(re.findall(r"^::: reeb\.(\w+)", page, re.M))
    modules = {"report", "dask", "__version__"}
    assert set(reeb.__all__) - modules <= documented, set(reeb.__all__) - modules - documented
