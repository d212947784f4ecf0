"""slamcommon.formats: the formats in a package the judge can import without the world: reading a TUM trajectory
imports neither Gymnasium, nor sim_envs, nor scipy; each format's reader is defined once in the tree."""

import ast
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[3]


def test_reading_a_trajectory_imports_no_world_no_gymnasium_no_scipy(tmp_path):
    path = tmp_path / "t.txt"
    path.write_text("1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n")
    code = (
        "import sys; import slamcommon.formats as f; import eval.metrics.tum_reader; "
        f"t, T = f.read_tum_trajectory({str(path)!r}); assert T.shape == (2, 4, 4); "
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('gymnasium', 'sim_envs', 'scipy')))"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_each_reader_and_the_association_are_defined_once():
    names = {"read_tum_trajectory", "read_tum_image_list", "read_kitti_poses", "read_pose_matrix", "associate_greedy",
             "matching_greedy", "read_tum_file", "quaternions_to_matrices", "parse_plain_tum_text", "greedy_candidates",
             "locally_first", "_data_lines", "_parse_numbers", "_check_increasing"}  # fmt: skip
    where: dict[str, list[str]] = {n: [] for n in names}
    for package in ("slamcommon", "sim_envs", "cnnslam", "eval", "thirdparty"):
        for path in (ROOT / package).rglob("*.py"):
            for node in ast.parse(path.read_text(), filename=str(path)).body:
                if isinstance(node, ast.FunctionDef) and node.name in where:
                    where[node.name].append(str(path.relative_to(ROOT)))
    assert {n: p for n, p in where.items() if len(p) > 1} == {}
    assert all(p[0].startswith("slamcommon/formats/") for p in where.values() if p)
