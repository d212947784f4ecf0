"""The test machinery's shared data (tests/conftest.py): found from the repository or $CNNSLAM_SHARED, a test skipped
with what is missing where it is absent; and tests/reference_facts.toml, the reference figures the tests assert: the
same as the notes they were copied from, and as the constants the code holds (camera presets, the paper's Table 1);
and the per-CPU byte digests (``pinned_bytes``)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[1]


def test_shared_data_is_found_beside_the_repository_or_where_the_variable_says(shared_data, monkeypatch, tmp_path):
    monkeypatch.delenv("CNNSLAM_SHARED", raising=False)
    (tmp_path / "data" / "tum").mkdir(parents=True)
    (tmp_path / "data" / "tum" / "a.txt").write_text("0 0 0 0 0 0 0 1\n")
    beside = (REPOSITORY.parent / "shared").resolve()
    with pytest.raises(pytest.skip.Exception) as skipped:
        shared_data("no/such/folder")
    assert str(beside / "no" / "such" / "folder") in str(skipped.value)
    assert "../shared beside the repository" in str(skipped.value) and "CNNSLAM_SHARED" in str(skipped.value)
    monkeypatch.setenv("CNNSLAM_SHARED", str(tmp_path))
    assert shared_data("data/tum", "a.txt") == tmp_path.resolve() / "data" / "tum"
    with pytest.raises(pytest.skip.Exception, match=re.escape(str(tmp_path.resolve() / "data" / "tum" / "b.txt"))):
        shared_data("data/tum", "a.txt", "b.txt")  # the folder is there, a file it must hold is not


def test_pinned_bytes_hold_each_cpu_to_its_own_and_skip_on_an_unrecorded_one(pinned_bytes, monkeypatch):
    monkeypatch.setitem(pinned_bytes.__globals__, "cpu_label", lambda: "Some CPU, avx2")
    recorded = {"unrecorded": "aaa", "Some CPU, avx2": "bbb"}
    assert pinned_bytes("bbb", recorded, "test_x") == "bbb"
    assert pinned_bytes("aaa", recorded, "test_x") == "bbb"  # another CPU's bytes are not this one's
    monkeypatch.setitem(pinned_bytes.__globals__, "cpu_label", lambda: "Other CPU, sse4_2")
    assert pinned_bytes("aaa", recorded, "test_x") == "aaa"  # a CPU not recorded: any recorded bytes pass
    with pytest.raises(pytest.skip.Exception, match=r"this CPU \(Other CPU, sse4_2\) .* test_x checks the figures"):
        pinned_bytes("ccc", recorded, "test_x")


def test_this_machines_cpu_label_names_its_model_and_widest_simd_extension(pinned_bytes):
    from eval.bench.environment import ISA_FLAGS, machine_description

    machine = machine_description()
    model, _, isa = pinned_bytes.__globals__["cpu_label"]().rpartition(", ")
    assert model == machine["cpu"] and isa in (*ISA_FLAGS, "none") and isa == (machine["isa"] or ["none"])[0]


def test_the_reference_facts_name_their_source_and_files(reference_facts):
    trajectory = reference_facts["trajectory"]
    assert "evo" in trajectory["source"] and "TUM RGB-D benchmark" in trajectory["source"]
    assert trajectory["max_difference"] == 0.02 and len(trajectory["cases"]) == 2
    for case in trajectory["cases"]:
        assert set(case["rmse"]) == {"tum", "nearest"}
        assert all(set(by_alignment) == {"se3", "sim3"} for by_alignment in case["rmse"].values())
        assert case["groundtruth"].endswith(".txt") and case["estimate"].endswith(".txt")


def test_the_reference_facts_are_the_notes_figures(shared_data, reference_facts):
    """Each case's row of the notes' table (section 2) holds the copied figures, in the table's column order: pairs,
    SE(3) and Sim(3) RMSE with the scale under the TUM association, SE(3) and Sim(3) RMSE under evo's."""
    notes = (shared_data("notes", "reference-facts.md") / "reference-facts.md").read_text()
    for case in reference_facts["trajectory"]["cases"]:
        row = f"| {case['groundtruth']} | {case['estimate']} |"
        rows = [line for line in notes.splitlines() if line.startswith(row)]
        assert len(rows) == 1, case["name"]
        cells = [cell.strip() for cell in rows[0].strip("|").split("|")][2:]
        rmse = case["rmse"]
        assert cells == [str(case["pairs"]), rmse["tum"]["se3"], f"{rmse['tum']['sim3']} ({case['scale']})",
                         rmse["nearest"]["se3"], rmse["nearest"]["sim3"]]  # fmt: skip
    assert "association tolerance 0.02 s" in notes
    for name, row in (("icl", "| ICL-NUIM |"), ("tum_fr1", "| TUM fr1 RGB |"), ("tum_fr2", "| TUM fr2 RGB |"),
                      ("tum_fr3", "| TUM fr3 RGB |"), ("tum_default", "| TUM default"), ("nyu", "| NYU Depth v2")):
        camera = reference_facts["cameras"][name]
        line = next(line for line in notes.splitlines() if line.startswith(row))
        cells = [cell.strip() for cell in line.strip("|").split("|")]
        assert [float(c) for c in cells[1:5]] == [camera[k] for k in ("fx", "fy", "cx", "cy")], name
        if "distortion" in camera:
            assert cells[6] == "distortion " + " ".join(f"{v:.4f}" for v in camera["distortion"]), name
    table1 = reference_facts["table1"]
    for method, row in (("CNN-SLAM", "| CNN-SLAM"), ("LSD-BS", "| LSD-SLAM with"), ("LSD", "| LSD-SLAM |"),
                        ("ORB", "| ORB-SLAM"), ("Laina", "| Laina"), ("REMODE", "| REMODE")):
        line = next(line for line in notes.splitlines() if line.startswith(row))
        ate, depth = (cell.strip() for cell in line.strip("|").split("|")[1:3])
        assert ate == (f"{table1['ate_m'][method]:.3f}" if method in table1["ate_m"] else "-"), method
        assert depth == f"{table1['correct_depth_percent'][method]:.3f}", method
    fcrn = reference_facts["fcrn"]
    assert f"{fcrn['parameters_millions']} M parameters" in notes
    assert f"rel {fcrn['nyu_v2_rel']}, rms {fcrn['nyu_v2_rms_m']} m" in notes


def test_the_code_holds_the_reference_cameras_and_the_papers_averages(reference_facts):
    from eval.reports.paper_table1 import PAPER_AVG_ATE, PAPER_AVG_CORRECT_DEPTH
    from sim_envs.camera import preset, preset_distortion

    for name, camera in reference_facts["cameras"].items():
        if name == "source":
            continue
        k = preset(name, 640, 480)
        fy = abs(camera["fy"])  # ICL-NUIM's official fy is negative (y flipped); OpenCV's y-down convention: +
        assert (k.fx, k.fy, k.cx, k.cy) == (camera["fx"], fy, camera["cx"], camera["cy"]), name
        assert preset_distortion(name) == tuple(camera.get("distortion", (0.0,) * 5)), name
    table1 = reference_facts["table1"]
    assert {m: v for m, v in PAPER_AVG_ATE.items() if v == v} == table1["ate_m"]  # REMODE's NaN: no ATE
    assert PAPER_AVG_CORRECT_DEPTH == table1["correct_depth_percent"]
