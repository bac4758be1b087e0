"""Provider names -> providers; unknown names are one-line UserErrors listing the valid ones."""
from __future__ import annotations

import importlib.util

import pytest

from nicer_stream.errors import UserError
from nicer_stream.priors import (
    DEPTH_NORMAL_PROVIDERS,
    FLOW_PROVIDERS,
    make_depth_normal_provider,
    make_flow_provider,
)


@pytest.mark.parametrize("name,label", [("none", "none"), ("oracle", "oracle")])
def test_depth_normal_names(name, label):
    assert make_depth_normal_provider(name, "cpu").name == label


@pytest.mark.parametrize("name", ["dis", "none", "oracle"])
def test_flow_names(name):
    p = make_flow_provider(name)
    assert p.name == name and p.active == (name != "none")


def test_default_flow_is_dis():
    assert make_flow_provider().name == "dis"


@pytest.mark.parametrize("name", ["midas", "oracle:x", "", "cache:"])
def test_unknown_depth_normal_provider(name):
    with pytest.raises(UserError) as e:
        make_depth_normal_provider(name)
    msg = str(e.value)
    assert "\n" not in msg
    if name != "cache:":
        assert all(p in msg for p in DEPTH_NORMAL_PROVIDERS)


@pytest.mark.parametrize("name", ["farneback", "dis:fast"])
def test_unknown_flow_provider(name):
    with pytest.raises(UserError) as e:
        make_flow_provider(name)
    msg = str(e.value)
    assert "\n" not in msg and all(p in msg for p in FLOW_PROVIDERS)


@pytest.mark.skipif(importlib.util.find_spec("torchvision") is not None, reason="torchvision installed")
def test_raft_without_torchvision_says_so():
    with pytest.raises(UserError) as e:
        make_flow_provider("raft")
    assert "raft needs torchvision" in str(e.value) and "\n" not in str(e.value)


def test_unreachable_omnidata_hub_is_a_user_error(tmp_path):
    """A directory without hubconf.py cannot load: the error says how to fix it, on one line."""
    with pytest.raises(UserError) as e:
        make_depth_normal_provider(f"omnidata:{tmp_path}")
    msg = str(e.value)
    assert "\n" not in msg and "omnidata:" in msg and str(tmp_path) in msg
