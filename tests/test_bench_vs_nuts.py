"""scripts/bench_vs_nuts.py: what runs without jax (arguments, the table, the goals' verdicts, the
missing-dependency message and exit code), and, where jax and numpyro are installed, JAX's log
posterior against the library's on a tiny grid and a short NUTS run."""

from __future__ import annotations

import ast
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


def _load():
    spec = importlib.util.spec_from_file_location("bench_vs_nuts", ROOT / "scripts" / "bench_vs_nuts.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_vs_nuts"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


bench = _load()


def test_the_script_does_not_import_jax():
    tree = ast.parse((ROOT / "scripts" / "bench_vs_nuts.py").read_text(encoding="utf-8"))
    top = [alias.name for node in tree.body if isinstance(node, ast.Import) for alias in node.names]
    top += [node.module for node in tree.body if isinstance(node, ast.ImportFrom)]
    assert "numpy" in top and not [name for name in top if name.split(".")[0] in ("jax", "numpyro", "nuts_reference")]


def test_defaults_and_arguments():
    args = bench.parse_args([])
    assert args.instances == ["small", "d50"] and args.methods == ["maxent_z", "sample_z"]
    assert (args.repeats, args.draws, args.nuts_warmup, args.nuts_mass, args.beta) == (3, 256, 200, "dense", 50.0)
    args = bench.parse_args(["--instances", "d50", "--methods", "sample_z", "--repeats", "1", "--nuts-mass", "diag"])
    assert (args.instances, args.methods, args.repeats, args.nuts_mass) == (["d50"], ["sample_z"], 1, "diag")
    for bad in (["--repeats", "0"], ["--instances", "huge"], ["--methods", "exact"], ["--draws", "-1"]):
        with pytest.raises(SystemExit):
            bench.parse_args(bad)


def test_the_instances_are_the_ones_the_issue_names():
    assert bench.INSTANCES == {"small": ("side_effects", 50), "d50": ("latent_raw", 50)}
    assert bench.GRAD_RTOL["maxent_z"] <= 1e-8 and bench.VALUE_RTOL <= 1e-8


def test_ratios():
    ours = bench.Measure(warmup=1.0, sampling=1.0, ess=200.0, r_hat=1.01)  # 100 ESS/s
    nuts = bench.Measure(warmup=8.0, sampling=2.0, ess=100.0, r_hat=1.0)  # 10 ESS/s total, 50 sampling
    assert bench.ratios(ours, nuts) == pytest.approx((10.0, 2.0))
    assert ours.total == 2.0


def test_verdicts():
    assert bench.verdict([10.0, 12.0, 30.0], 10.0) == "met"
    assert bench.verdict([5.0, 12.0, 30.0], 10.0) == "met at the median only"
    assert bench.verdict([5.0, 6.0, 30.0], 10.0) == "MISSED"
    assert bench.min_median([3.0, 1.0, 2.0]) == "1.0 / 2.0"


def test_table_row_and_goal_lines():
    pairs = [(bench.Measure(1.0, 1.0, 200.0, 1.01), bench.Measure(8.0, 2.0, 100.0, 1.0, "31")),
             (bench.Measure(1.0, 3.0, 400.0, 1.03), bench.Measure(6.0, 2.0, 100.0, 1.02, "29"))]
    row = bench.table_row("d50 (latent_raw, d = 50)", "maxent_z", "4 x 256", pairs)
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert len(cells) == bench.TABLE_HEADER.splitlines()[0].count("|") - 1 == 11
    assert cells[:3] == ["d50 (latent_raw, d = 50)", "maxent_z", "4 x 256"]
    assert cells[3] == "3.0 (1.0 + 2.0)"  # medians of the repeats
    assert cells[7] == "31"
    assert cells[9] == "8.0 / 9.0"  # 10x and 8x total ratios (min / median)
    assert cells[10] == "2.0 / 2.0"
    lines = bench.goal_lines({("d50", "maxent_z"): pairs})
    assert lines == ["d50 maxent_z: >= 10x NUTS ESS/s MISSED (8.0 / 9.0x); >= 2x NUTS's sampling phase met (2.0 / 2.0x)"]


def test_missing_dependencies_print_the_command_and_exit_2(monkeypatch, capsys):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name in ("jax", "numpyro") else real(name, *a))
    assert bench.missing_dependencies() == ["jax", "numpyro"]
    calls = []
    assert bench.ensure_dependencies(False, run=calls.append) == bench.EXIT_MISSING == 2
    assert calls == []  # never installs without --install
    err = capsys.readouterr().err
    assert "jax and numpyro not installed" in err and bench.INSTALL_COMMAND in err
    assert "requirements-bench.txt -c " in bench.INSTALL_COMMAND and bench.INSTALL_COMMAND.endswith("requirements.txt")
    assert bench.main(["--check-only"]) == 2


def test_install_runs_the_command(monkeypatch):
    state = {"installed": False}
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: (real("json") if state["installed"] else None) if name in ("jax", "numpyro")
                        else real(name, *a))
    commands = []

    def run(command):
        commands.append(command)
        state["installed"] = True
        return 0

    assert bench.ensure_dependencies(True, run=run) is None
    assert commands and commands[0][1:4] == ["-m", "pip", "install"] and "requirements-bench.txt" in commands[0][5]


def test_requirements_bench_pins_and_is_not_in_the_setup():
    pins = [line for line in (ROOT / "requirements-bench.txt").read_text().splitlines() if line and line[0].isalpha()]
    assert {p.split("==")[0] for p in pins} >= {"numpyro", "jax", "jaxlib"} and all("==" in p for p in pins)
    for path in ("scripts/bootstrap.sh", "requirements.txt", "requirements-docs.txt"):
        text = (ROOT / path).read_text()
        assert "requirements-bench" not in text and "numpyro" not in text.lower()


def test_jax_agrees_with_the_library_on_a_tiny_grid():
    pytest.importorskip("jax")
    pytest.importorskip("numpyro")
    sys.path.insert(0, str(ROOT / "scripts" / "lib"))
    try:
        import nuts_reference
    finally:
        sys.path.remove(str(ROOT / "scripts" / "lib"))
    from ird_core import mdp, posterior

    rng = np.random.default_rng(3)
    grid = mdp.GridMDP(rng.uniform(0, 1, (4, 5, 3)), (1, 2), 5)
    proxy = np.array([1.0, -0.5, 0.3])
    weights = rng.standard_normal((4, 3))
    for method, grad_rtol in (("maxent_z", 1e-8), ("sample_z", 1e-5)):
        model = posterior.make_posterior_model(proxy, grid, 5.0, method, num_proxy_samples=50, seed=1)
        log_density = nuts_reference.log_density_fn(model)
        v_err, g_err = nuts_reference.check_agreement(model, log_density, weights, 1e-10, grad_rtol)
        assert v_err <= 1e-10 and g_err <= grad_rtol
        with pytest.raises(AssertionError):  # the check can fail: another beta is another posterior
            other = posterior.make_posterior_model(proxy, grid, 6.0, method, num_proxy_samples=50, seed=1)
            nuts_reference.check_agreement(other, log_density, weights, 1e-10, grad_rtol)
    runner = nuts_reference.NutsRunner(log_density, 3, num_warmup=30, num_draws=20)
    runner.compile()
    run = runner.run(2, seed=0)
    assert run.draws.shape == (2, 20, 3) and np.all(np.isfinite(run.draws))
    assert run.warmup_seconds > 0 and run.sampling_seconds > 0
