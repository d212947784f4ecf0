"""The calibration's view of other machines: the matrix's "another-isa" configuration really moves each library to
an older code path (checked in a fresh interpreter, as the suite's workers are spawned with the variables set), and
other machines' records join the calibration only when they were made from the same runs."""

import json
import math
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from eval.bench.calibrate import (
    MATRIX,
    OLDER_ISA,
    calibrated_baseline,
    load_machine_records,
    machine_file_name,
    save_machine_record,
)
from eval.bench.gate_baseline import ADDED_KEY, REWRITTEN_KEY, UNGATED_KEY, load_baseline
from eval.bench.regress import calibrate, compare
from eval.bench.suites import get_suite

PROBE = """
import json
import cv2, numba, numpy, torch
from numpy._core._multiarray_umath import __cpu_features__
print(json.dumps({
    "numpy_x86_v3": bool(__cpu_features__.get("X86_V3", False)),
    "opencv": cv2.getCPUFeaturesLine(),
    "numba_cpu": numba.config.CPU_NAME,
    "torch": torch.backends.cpu.get_cpu_capability(),
}))
"""


def _probe(env: dict[str, str]) -> dict:
    out = subprocess.run([sys.executable, "-c", PROBE], env={**os.environ, **env}, capture_output=True, text=True,
                         check=True, timeout=300)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_another_isa_is_in_the_matrix_with_the_older_code_paths():
    (config,) = [c for c in MATRIX if c.name == "another-isa"]
    assert config.env == OLDER_ISA
    assert config.jobs == MATRIX[0].jobs  # only the instruction set differs from the reference


def test_the_variables_select_older_code_paths_in_each_library():
    older = _probe(OLDER_ISA)
    assert older["numpy_x86_v3"] is False  # numpy's AVX2/FMA3 (x86-64-v3) kernels off
    assert "AVX2?" in older["opencv"] or "AVX2" not in older["opencv"]  # OpenCV: AVX2 disabled or absent
    assert older["numba_cpu"] == "generic"
    assert older["torch"] == "DEFAULT"  # ATen without vectorised kernels


def _record(suite: str, fingerprints: list[str], metrics: dict, cpu: str) -> dict:
    return {"schema": "cnnslam-machine-figures/1", "suite": suite, "revision": "abc",
            "environment": {"cpu": cpu, "isa": ["avx2"], "cores": 2}, "fingerprints": fingerprints,
            "metrics": metrics}


def test_machine_records_of_the_same_runs_join_the_calibration_and_others_are_left_out(tmp_path):
    same = save_machine_record(_record("quick", ["b", "a"], {"x/ate_rmse": 0.2, "x/depth": math.nan}, "Other CPU"),
                               tmp_path)
    save_machine_record(_record("quick", ["a", "c"], {"x/ate_rmse": 9.0}, "Stale CPU"), tmp_path)
    save_machine_record(_record("table1", ["a", "b"], {"x/ate_rmse": 9.0}, "Table CPU"), tmp_path)
    own = save_machine_record(_record("quick", ["a", "b"], {"x/ate_rmse": 0.1}, "This CPU"), tmp_path)
    usable, left_out = load_machine_records(tmp_path, "quick", ["a", "b"], exclude=own.name)
    assert list(usable) == [f"machine:{same.stem}"]
    assert usable[f"machine:{same.stem}"]["x/ate_rmse"] == 0.2
    assert math.isnan(usable[f"machine:{same.stem}"]["x/depth"])  # NaN is stored as null and read back
    assert len(left_out) == 2 and any("other runs" in w for w in left_out) and any("table1" in w for w in left_out)
    assert machine_file_name({"cpu": "Intel(R) Xeon(R)", "isa": ["avx512f"], "cores": 2}) == \
        "intel-r-xeon-r-avx512f-2cores.json"


def test_another_machine_widens_the_tolerance_to_cover_its_figures():
    figures = {"reference": {"m/ate_rmse": 0.100}, "threads2": {"m/ate_rmse": 0.100}}
    runs = {"reference": {0: {"m/ate_rmse": 0.100}}, "threads2": {0: {"m/ate_rmse": 0.100}}}
    suite = get_suite("quick")
    records = {"reference": [], "threads2": []}
    with pytest.raises(ValueError, match="named like configurations"):
        calibrated_baseline(suite, records, "d", MATRIX[:2], machines={"threads2": {"m/ate_rmse": 0.2}})
    alone = calibrate(figures, "reference", runs=runs)
    both = calibrate({**figures, "machine:other": {"m/ate_rmse": 0.120}}, "reference", runs=runs)
    assert compare(alone, {"m/ate_rmse": 0.120}).passed is False
    assert compare(both, {"m/ate_rmse": 0.120}).passed
    assert both.calibrated["m/ate_rmse"]["spread"] == pytest.approx(0.020)


def test_every_committed_machine_record_of_the_baseline_s_runs_passes_it():
    """The machine the baseline was calibrated on (its record holds the baseline's figures) and every other machine
    whose record was made from the same runs pass the committed baseline; a record of other runs (e.g. made before
    an intended change of results, until it is remade on its machine) is left out, as ``--calibrate`` leaves it out."""
    root = Path(__file__).resolve().parents[3] / "results" / "baselines"
    baseline = load_baseline(root / "quick.json")
    folder = root / "machines" / "quick"
    records = {path.name: json.loads(path.read_text()) for path in sorted(folder.glob("*.json"))}
    added = set(baseline.calibration.get(ADDED_KEY, []))  # figures gated after the calibration (only_new, merge)
    rewritten = set(baseline.calibration.get(REWRITTEN_KEY, []))  # given new values after it (merge)
    rewritten |= set(baseline.calibration.get(UNGATED_KEY, {}))  # left out of the gate as noise: in no comparison
    later = added | rewritten  # in no machine record made at the calibration
    own = {k: v for k, v in json.loads((root / "quick.json").read_text())["metrics"].items() if k not in later}
    home = [name for name, r in records.items()
            if {k: v for k, v in r["metrics"].items() if k not in rewritten} == own]
    assert len(home) == 1, f"no machine record holds the baseline's own figures: {sorted(records)}"
    same, left_out = load_machine_records(folder, "quick", records[home[0]]["fingerprints"], exclude=home[0])
    for name, figures in {home[0]: records[home[0]]["metrics"], **same}.items():
        figures = {k: math.nan if v is None else v for k, v in figures.items() if k not in rewritten}
        held = replace(baseline, metrics={k: v for k, v in baseline.metrics.items() if k not in later})
        assert compare(held, figures).passed, name
    assert all("made from other runs" in why for why in left_out), left_out


def test_network_perturbations_are_explicit_predictor_options():
    """No environment channel into the agent: the matrix's network switches are predictor options merged into the
    network methods' definitions (so their fingerprints differ), and only theirs."""
    from eval.bench.methods import load_methods

    methods = load_methods()
    (cpu,) = [c for c in MATRIX if c.name == "another-cpu"]
    (onednn,) = [c for c in MATRIX if c.name == "onednn-off"]
    assert not cpu.env and not onednn.env
    perturbed = cpu.methods(methods)
    cnn = perturbed["CNN-SLAM"].agent_kwargs(0)
    assert cnn["predictor_options"] == {"jitter_seed": 0, "jitter_seed_fallback": 1009}
    assert perturbed["CNN-SLAM"].describe() != methods["CNN-SLAM"].describe()
    assert perturbed["LSD"] == methods["LSD"] and perturbed["dev-depth-5"] == methods["dev-depth-5"]
    assert onednn.methods(methods)["CNN-SLAM"].agent_kwargs(1)["predictor_options"] == {"jitter_seed": 1,
                                                                                          "onednn": False}
