"""eval.bench.method_settings: ``--set KEY=VALUE`` parsed as TOML values, merged into a method's agent keywords (and so
its run fingerprint), refused with one line where the text or the method cannot take it."""

import pytest

from eval.bench.method_settings import parse_setting, with_predictor_options, with_settings
from eval.bench.methods import Method, MethodError


def test_a_setting_is_parsed_as_a_toml_value_or_kept_as_text():
    assert parse_setting("refinement.enabled=false") == ("refinement.enabled", False)
    assert parse_setting("tracking.max_iterations = 12") == ("tracking.max_iterations", 12)
    assert parse_setting("x=[1, 2]") == ("x", [1, 2])
    assert parse_setting("name=plain words") == ("name", "plain words")
    for bad in ("no_equals", "=5", "a..b=1"):
        with pytest.raises(MethodError, match="KEY=VALUE"):
            parse_setting(bad)


def test_settings_and_predictor_options_are_merged_into_the_agent_keywords():
    method = Method("CNN-SLAM", entry_point="cnnslam.agent:CnnSlamAgent", kwargs={"preset": "cnn_slam"})
    changed = with_settings(method, [("refinement.enabled", False), ("refinement.enabled", True)])
    assert dict(changed.agent_kwargs(0))["config"] == {"refinement.enabled": True}  # later ones win
    assert with_settings(method, []) is method
    opts = with_predictor_options(changed, {"onednn": False})
    kwargs = dict(opts.agent_kwargs(0))
    assert kwargs["predictor_options"] == {"onednn": False} and kwargs["config"] == {"refinement.enabled": True}


def test_a_method_without_a_configuration_is_refused():
    external = Method("Theirs", kind="external", folder="somewhere")  # a folder of trajectories: nothing to set
    with pytest.raises(MethodError, match="takes no configuration"):
        with_settings(external, [("a.b", 1)])
