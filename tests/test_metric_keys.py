"""Each metric's key is spelled in at most two source files: the catalogue (:mod:`eval.metrics.catalogue`) and the
one place that computes it; every other reader and writer takes ``catalogue.<NAME>.key`` (the agent's own keys:
:mod:`slamcommon.agent_keys`). A key that is an ordinary word (``frames``, ``fps``, ``scale``: no underscore) is left
out, since the word is everywhere for other reasons."""

import re
from pathlib import Path

from eval.metrics.catalogue import CATALOGUE

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("slamcommon", "sim_envs", "cnnslam", "eval", "thirdparty")
MOST_FILES = 2
# a third file that spells a key for another quantity, each with why it stays for now; the list only shrinks
OTHER_QUANTITY = {
    # ORB's own count of its map's good points in its agent_extras.json (not the fused model's points the map metric
    # counts); renaming it changes ORB's run fingerprints, so it goes with the next remake of ORB's runs
    "map_points": "cnnslam/baselines/orb.py",
}


def files_spelling(key: str, texts: dict[str, str]) -> list[str]:
    """The files whose text holds ``key`` as a whole word (as ``git grep -w`` finds it)."""
    word = re.compile(rf"(?<!\w){re.escape(key)}(?!\w)")
    return sorted(name for name, text in texts.items() if word.search(text))


def test_files_spelling_finds_whole_words_only():
    texts = {"a.py": 'x["wall_s"]', "b.py": "scoring_wall_s = 1", "c.py": "# wall_s of a run", "d.py": "wall_sx"}
    assert files_spelling("wall_s", texts) == ["a.py", "c.py"]


def test_each_metric_key_is_spelled_in_at_most_two_files():
    texts = {str(p.relative_to(ROOT)): p.read_text() for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}
    assert len(texts) > 200
    keys = [spec.key for spec in CATALOGUE if "_" in spec.key]
    assert len(keys) >= 40
    spelled = {k: files_spelling(k, texts) for k in keys}
    counted = {k: [f for f in files if f != OTHER_QUANTITY.get(k)] for k, files in spelled.items()}
    over = {k: files for k, files in counted.items() if len(files) > MOST_FILES}
    assert over == {}
    assert all(OTHER_QUANTITY[k] in spelled[k] for k in OTHER_QUANTITY)  # an excused file that no longer spells it goes
