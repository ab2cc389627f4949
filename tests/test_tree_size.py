"""scripts/check_tree_size.py: CI's limits on the tracked tree (a file over 2 MiB, a tree over 15 MB,
outside descriptions/) are found and named."""

import importlib.util

from conftest import REPO

spec = importlib.util.spec_from_file_location("check_tree_size", REPO / "scripts/check_tree_size.py")
check = importlib.util.module_from_spec(spec)
spec.loader.exec_module(check)


def test_a_large_file_and_a_large_tree_are_named():
    assert check.problems({"a.py": 1000, "policies/p/video_0.gif": 290_000}) == []
    (line,) = check.problems({"a.py": 1000, "benchmarks/x/jax_cache.tar.gz": 3 * 2**20})
    assert line.startswith("benchmarks/x/jax_cache.tar.gz: 3.00 MiB, over the 2 MiB")
    many = {f"policies/p/{i}.bin": 2**20 for i in range(16)}  # 16.8 MB, each file within its limit
    (line,) = check.problems(many)
    assert (
        "the tracked tree outside descriptions/ is 16.8 MB, over 15 MB" in line and "policies/p/0.bin (1.0 MB)" in line
    )


def test_descriptions_are_exempt_and_only_tracked_files_count():
    sizes = check.tracked_sizes()
    assert sizes and not any(name.startswith("descriptions/") for name in sizes)
    assert "scripts/check_tree_size.py" in sizes and not any(name.startswith(("runs/", ".venv/")) for name in sizes)
