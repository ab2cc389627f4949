"""Output folders: `--out` never deletes what footforge did not write, a bad `--out` fails first
(exit 2, one line), killed runs leave no workers and no temporary folders behind."""

import importlib.util
import json
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from footforge.atomic import atomic_directory, remove_stale_temporaries, remove_stale_temporaries_in
from footforge.cli.main import main
from footforge.errors import InputError
from footforge.outputs import MARKER, check_output_folder, write_marker

from conftest import REPO


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out + out.err


def never(*args, **kwargs):
    pytest.fail("the long work started although --out was refusable")


@pytest.fixture
def user_folder(tmp_path):
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "thesis.tex").write_text("years of work")
    return folder


def load_pipeline(name):
    spec = importlib.util.spec_from_file_location(f"pipeline_{name}", REPO / "pipelines" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# --- a folder with the user's files is refused, before the work, and left intact ---


def test_build_refuses_folder_with_user_files(capsys, monkeypatch, user_folder):
    monkeypatch.setattr("footforge.build.pipeline.load_foot_source", never)
    monkeypatch.setattr("footforge.build.pipeline.load_params", never)
    code, text = run(capsys, "build", "--variant", "aff", "--out", user_folder)
    assert code == 2, text
    assert str(user_folder) in text.replace("\n", "") and "--force" in text and "Traceback" not in text
    assert (user_folder / "thesis.tex").read_text() == "years of work"
    assert [p.name for p in user_folder.parent.iterdir()] == ["mine"]


def test_validate_refuses_folder_with_user_files(capsys, monkeypatch, user_folder):
    monkeypatch.setattr("footforge.validate.runner.validate", never)
    code, text = run(capsys, "validate", "--variant", "aff", "--jobs", "1", "--out", user_folder)
    assert code == 2, text
    assert "--force" in text and (user_folder / "thesis.tex").is_file()


def test_evaluate_pipeline_refuses_folder_with_user_files(capsys, monkeypatch, user_folder):
    monkeypatch.setattr("footforge.rl.evaluate.evaluate", never)
    code = load_pipeline("evaluate").main(
        ["--policy", str(user_folder / "policy"), "--feet", "aff", "--out", str(user_folder)]
    )
    text = capsys.readouterr().err
    assert code == 2, text
    assert f"--out {user_folder}" in text and "--force" in text and len(text.strip().splitlines()) == 1
    assert (user_folder / "thesis.tex").read_text() == "years of work"


def test_closed_chain_pipeline_refuses_folder_with_user_files(capsys, monkeypatch, user_folder):
    monkeypatch.setattr("footforge.rl.evaluate_closed_chain.evaluate_closed_chain", never)
    code = load_pipeline("evaluate_closed_chain").main(
        ["--policy", str(user_folder / "policy"), "--out", str(user_folder)]
    )
    text = capsys.readouterr().err
    assert code == 2, text
    assert "--force" in text and (user_folder / "thesis.tex").is_file()


# --- bad paths: refused first, exit 2, one line naming the path ---


def test_build_refuses_existing_file(capsys, monkeypatch, tmp_path):
    monkeypatch.setattr("footforge.build.pipeline.load_params", never)
    target = tmp_path / "notes.txt"
    target.write_text("mine")
    code, text = run(capsys, "build", "--variant", "aff", "--out", target)
    assert code == 2 and "is a file" in text and "Traceback" not in text
    assert target.read_text() == "mine" and [p.name for p in tmp_path.iterdir()] == ["notes.txt"]


def test_build_refuses_path_under_a_file(capsys, monkeypatch, tmp_path):
    monkeypatch.setattr("footforge.build.pipeline.load_params", never)
    (tmp_path / "notes.txt").write_text("mine")
    code, text = run(capsys, "build", "--variant", "aff", "--out", tmp_path / "notes.txt" / "out")
    assert code == 2 and "notes.txt is a file" in text.replace("\n", "") and "Traceback" not in text


def test_build_refuses_current_folder(capsys, monkeypatch, tmp_path):
    monkeypatch.setattr("footforge.build.pipeline.load_params", never)
    monkeypatch.chdir(tmp_path)
    code, text = run(capsys, "build", "--variant", "aff", "--out", ".", "--force")
    assert code == 2 and "current folder" in text


def _owner_access(path, mode, **kw):
    """os.access as the folder's unprivileged owner sees it: the owner permission bits. Root passes
    every access check whatever the bits, and CI runs as root."""
    bits = os.stat(path).st_mode
    wanted = {os.W_OK: 0o200, os.X_OK: 0o100, os.R_OK: 0o400}
    return all(bits & b for m, b in wanted.items() if mode & m)


def test_build_refuses_unwritable_parent(capsys, monkeypatch, tmp_path):
    monkeypatch.setattr("footforge.build.pipeline.load_params", never)
    if os.geteuid() == 0:
        monkeypatch.setattr(os, "access", _owner_access)
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        code, text = run(capsys, "build", "--variant", "aff", "--out", locked / "out")
    finally:
        locked.chmod(0o700)
    assert code == 2 and "cannot write" in text


# --- what may be replaced ---


def test_folder_footforge_wrote_is_replaced(tmp_path):
    out = tmp_path / "out"
    with atomic_directory(out, command="first") as tmp:
        (tmp / "old.txt").write_text("1")
    assert (out / MARKER).is_file() and '"first"' in (out / MARKER).read_text()
    with atomic_directory(out, command="second") as tmp:
        (tmp / "new.txt").write_text("2")
    assert sorted(p.name for p in out.iterdir()) == sorted([MARKER, "new.txt"])
    assert [p.name for p in tmp_path.iterdir()] == ["out"]  # no temporary or set-aside folder


def test_a_linked_output_folder_is_written_through_its_link(tmp_path):
    """`--out build/aof` where build/aof links to a folder footforge wrote elsewhere: the link
    stays a link and its target gets the new output (the link used to be renamed aside, left
    behind as .aof.old-PID, and replaced by a plain folder)."""
    target, links = tmp_path / "kit" / "aof", tmp_path / "build"
    with atomic_directory(target, command="first") as tmp:
        (tmp / "old.txt").write_text("1")
    links.mkdir()
    (links / "aof").symlink_to(target)
    with atomic_directory(links / "aof", command="second") as tmp:
        (tmp / "new.txt").write_text("2")
    assert (links / "aof").is_symlink() and (links / "aof").resolve() == target.resolve()
    assert sorted(p.name for p in target.iterdir()) == sorted([MARKER, "new.txt"])
    assert [p.name for p in links.iterdir()] == ["aof"] and [p.name for p in target.parent.iterdir()] == ["aof"]


def test_a_link_is_checked_as_the_folder_it_points_to(tmp_path, user_folder, monkeypatch):
    """Before any work: a broken link, a link to a user's folder (unless --force) and a link to
    the current folder are refused, each naming the path as given."""
    (tmp_path / "broken").symlink_to(tmp_path / "nowhere")
    (tmp_path / "linked").symlink_to(user_folder)
    (tmp_path / "here").symlink_to(tmp_path)
    monkeypatch.chdir(tmp_path)
    for name, message in (("broken", "broken link"), ("linked", "--force"), ("here", "links to the current folder")):
        with pytest.raises(InputError, match=message) as refused:
            with atomic_directory(Path(name)):
                pytest.fail(f"the body ran although {name} was refused")
        assert str(refused.value).startswith(f"--out {name}:")
    assert not (tmp_path / "nowhere").exists() and (user_folder / "thesis.tex").is_file()


def test_build_replaces_its_own_output_folder(capsys, tmp_path):
    out = tmp_path / "out"
    for _ in range(2):
        code, text = run(capsys, "build", "--variant", "ball", "--format", "mjcf", "--out", out)
        assert code == 0, text
    marker = json.loads((out / MARKER).read_text())
    assert marker["tool"] == "footforge" and marker["version"] and "command" in marker
    assert (out / "scene.xml").is_file() and [p.name for p in tmp_path.iterdir()] == ["out"]


def test_empty_folder_is_filled_and_force_replaces_user_folder(tmp_path, user_folder):
    empty = tmp_path / "empty"
    empty.mkdir()
    with atomic_directory(empty) as tmp:
        (tmp / "a").write_text("a")
    assert (empty / "a").is_file()
    with pytest.raises(InputError, match="--force"):
        with atomic_directory(user_folder):
            pytest.fail("the body ran although the folder was refused")
    assert (user_folder / "thesis.tex").is_file()
    with atomic_directory(user_folder, force=True) as tmp:
        (tmp / "b").write_text("b")
    assert not (user_folder / "thesis.tex").exists() and (user_folder / "b").is_file()


def test_user_files_appearing_during_the_run_are_kept(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(InputError):
        with atomic_directory(out) as tmp:
            (tmp / "result").write_text("r")
            out.mkdir()
            (out / "mine.txt").write_text("mine")
    assert (out / "mine.txt").read_text() == "mine"
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_check_output_folder_is_reusable(tmp_path):
    """Training's run folder can use the same check, with its own flag names."""
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "x").write_text("x")
    with pytest.raises(InputError, match="--run-dir .*--overwrite"):
        check_output_folder(run_dir, flag="--run-dir", force_flag="--overwrite")
    write_marker(run_dir, "train")
    assert check_output_folder(run_dir) == run_dir


# --- killed runs ---


def dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait(timeout=60)
    return proc.pid


def test_stale_temporaries_of_dead_runs_are_removed(tmp_path):
    out = tmp_path / "out"
    stale = tmp_path / f".out.tmp-{dead_pid()}-abc123"
    stale_old = tmp_path / f".out.old-{dead_pid()}"
    live = tmp_path / f".out.tmp-{os.getppid()}-def456"  # a running process's: still being written
    other = tmp_path / f".output.tmp-{dead_pid()}-x"  # another folder's
    for folder in (stale, stale_old, live, other):
        folder.mkdir()
        (folder / "robot.xml").write_text("<mujoco/>")
    with atomic_directory(out) as tmp:
        (tmp / "a").write_text("a")
    assert not stale.exists() and not stale_old.exists()
    assert live.is_dir() and other.is_dir() and (out / "a").is_file()
    assert remove_stale_temporaries(out) == []


def test_stale_temporaries_of_every_output_in_a_folder_are_removed(tmp_path):
    """remove_stale_temporaries_in finds the leftovers of outputs that no longer exist, and only dead
    runs' leftovers with atomic_directory's names."""
    gone = [tmp_path / f".000123.tmp-{dead_pid()}-abc123", tmp_path / f".policy.old-{dead_pid()}"]
    kept = [
        tmp_path / f".000456.tmp-{os.getppid()}-def456",  # a running process's
        tmp_path / f".notes.tmp-{dead_pid()}",  # not a name atomic_directory gives (no mkdtemp suffix)
        tmp_path / "000789",  # an output itself
    ]
    for folder in gone + kept:
        folder.mkdir()
    user_file = tmp_path / f".a.old-{dead_pid()}"
    user_file.write_text("a user's file, not a folder")
    assert sorted(remove_stale_temporaries_in(tmp_path)) == sorted(gone)
    assert all(not p.exists() for p in gone) and all(p.is_dir() for p in kept) and user_file.is_file()


def process_gone(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return True
    return state in ("Z", "X")  # a zombie has exited; its new parent reaps it


def children_of(pid: int) -> list[int]:
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def kill_parent_and_wait_for(parent: subprocess.Popen, workers: list[int], timeout_s: float = 10.0) -> list[int]:
    """Kills `parent` and waits, up to `timeout_s`, for each of `workers` (not this process's
    children) to exit: a pidfd becomes readable when its process exits. Returns those still alive."""
    pidfds = {}
    for w in workers:
        try:
            pidfds[w] = os.pidfd_open(w)
        except ProcessLookupError:  # gone already
            pass
    parent.send_signal(signal.SIGKILL)
    parent.wait(timeout=120)
    try:
        waiting = select.poll()
        for fd in pidfds.values():
            waiting.register(fd, select.POLLIN)
        deadline = time.monotonic() + timeout_s
        exited: set[int] = set()
        while len(exited) < len(pidfds) and (left := deadline - time.monotonic()) > 0:
            exited |= {fd for fd, _ in waiting.poll(left * 1000)}
    finally:
        for fd in pidfds.values():
            os.close(fd)
    alive = [w for w in workers if not process_gone(w)]
    for w in alive:  # do not leave them running when the test fails
        os.kill(w, signal.SIGKILL)
    return alive


PARENT_WITH_POOL = """
import os, sys
from footforge.validate.runner import Pool
pool = Pool(2)
pids = {pool._pool.submit(os.getpid).result() for _ in range(8)}
print(" ".join(map(str, sorted(pids))), flush=True)
sys.stdin.read()  # until killed
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_validate_pool_workers_exit_when_parent_is_killed(tmp_path):
    env = os.environ | {"PYTHONPATH": str(REPO)}
    parent = subprocess.Popen(
        [sys.executable, "-c", PARENT_WITH_POOL], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env
    )
    workers = [int(p) for p in parent.stdout.readline().split()]
    assert workers and all(not process_gone(w) for w in workers)
    assert kill_parent_and_wait_for(parent, workers) == []


FAKE_COACD = """
def set_log_level(level):
    pass


def Mesh(vertices, faces):
    return None


def run_coacd(mesh, **kwargs):
    print("coacd running", flush=True)
    return sum(range(10 ** 13))  # minutes in C code that holds the GIL, as CoACD does
"""

PARENT_WITH_COACD = """
import trimesh
from pathlib import Path
from footforge.models.collision import DecompositionConfig, _run_coacd
_run_coacd(Path("fake.stl"), trimesh.creation.box(), DecompositionConfig(timeout_s=600))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_coacd_worker_exits_when_build_is_killed(tmp_path):
    (tmp_path / "coacd.py").write_text(FAKE_COACD)
    env = os.environ | {"PYTHONPATH": os.pathsep.join([str(tmp_path), str(REPO)])}
    parent = subprocess.Popen([sys.executable, "-c", PARENT_WITH_COACD], env=env, stdout=subprocess.PIPE, text=True)
    # The fake CoACD says when it enters its GIL-holding loop (its worker shares the parent's stdout).
    assert parent.stdout.readline() == "coacd running\n", "the CoACD worker did not start"
    workers = [
        c for c in children_of(parent.pid) if "spawn_main" in Path(f"/proc/{c}/cmdline").read_text(errors="replace")
    ]
    assert workers, "the CoACD worker is not the parent's child"
    assert kill_parent_and_wait_for(parent, workers) == []


# --- SIGTERM is handled like Ctrl-C ---


def test_sigterm_during_build_cleans_up_like_ctrl_c(capsys, monkeypatch, tmp_path):
    def terminated(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)
        pytest.fail("SIGTERM did not interrupt")

    monkeypatch.setattr("footforge.build.pipeline.load_params", terminated)
    before = signal.getsignal(signal.SIGTERM)
    code, text = run(capsys, "build", "--variant", "aff", "--out", tmp_path / "out")
    assert code == 143 and "footforge build: terminated; no output was written" in text  # 128 + SIGTERM, as shells say
    assert list(tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) == before  # restored


def test_a_build_folder_from_before_the_marker_counts_as_footforge_s(tmp_path):
    """Builds written before the marker existed carry footforge's build_report.json: replaced
    without --force; a folder whose report is not footforge's still needs it."""
    import json

    from footforge.outputs import check_output_folder

    old = tmp_path / "old"
    old.mkdir()
    (old / "build_report.json").write_text(json.dumps({"variant": "aof", "versions": {"footforge": "0.1.0"}}))
    (old / "robot.xml").write_text("<mujoco/>")
    check_output_folder(old)  # no error
    other = tmp_path / "other"
    other.mkdir()
    (other / "build_report.json").write_text(json.dumps({"my": "data"}))
    with pytest.raises(InputError):
        check_output_folder(other)
