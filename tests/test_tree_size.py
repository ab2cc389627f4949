"""scripts/check_tree_size.py: CI's limits on the tracked tree (a file over 2 MiB, a tree over 15 MB
outside descriptions/ and the policies' weights, weights over 30 MB) are found and named."""

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
    assert "outside descriptions/ and the policies' weights is 16.8 MB, over 15 MB" in line
    assert "policies/p/0.bin (1.0 MB)" in line


def test_the_policies_weights_have_a_budget_of_their_own():
    """Weights (a policy's policy/ and checkpoints/) count apart: 16 MB of them leave the tree's 15 MB alone,
    31 MB are over their 30 MB; a file elsewhere in a policy folder counts with the tree."""
    weights = {f"policies/rough_{i}/policy/d/{i}": 1_000_000 for i in range(16)}
    weights |= {f"policies/rough_x/checkpoints/000000000064/d/{i}": 10 for i in range(3)}
    docs = {f"docs/{i}.md": 1_000_000 for i in range(14)}
    assert check.problems(weights | docs) == []
    (line,) = check.problems(weights | docs | {"policies/rough_0/metrics.jsonl": 1_500_000})
    assert "the tracked tree outside descriptions/ and the policies' weights is 15.5 MB, over 15 MB" in line
    more = {f"policies/rough_{i}/checkpoints/000000000064/d/{i}": 1_000_000 for i in range(16, 31)}
    (line,) = check.problems(weights | more)
    assert "the policies' weights (policy/, checkpoints/) is 31.0 MB, over 30 MB" in line


def test_descriptions_are_exempt_and_only_tracked_files_count():
    sizes = check.tracked_sizes()
    assert sizes and not any(name.startswith("descriptions/") for name in sizes)
    assert "scripts/check_tree_size.py" in sizes and not any(name.startswith(("runs/", ".venv/")) for name in sizes)
