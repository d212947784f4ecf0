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
    over = {k: files for k in keys if len(files := files_spelling(k, texts)) > MOST_FILES}
    assert over == {}
