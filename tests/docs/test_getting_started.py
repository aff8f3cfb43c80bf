"""docs/getting_started.md's install notes against the packages' own pins."""
from __future__ import annotations

import re
from importlib import metadata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def test_the_page_names_the_gymnasium_version_rllib_pins():
    """Regression (issue 52): the full install (the dev extra, through ray[rllib]) silently moved Gymnasium from
    1.4.0 to 1.2.2 and no page said so. The getting-started page names the pin, which must be Ray's own, and
    crowd_env's own range."""
    text = " ".join((ROOT / "docs" / "getting_started.md").read_text().split())
    pyproject = (ROOT / "pyproject.toml").read_text()
    assert '"gymnasium>=1.0,<=1.4.99"' in pyproject and "accepts Gymnasium 1.0 to 1.4 (`pyproject.toml`)" in text
    dev = re.search(r"^dev = \[(.*?)\]\n", pyproject, re.M | re.S).group(1)
    assert re.search(r"crowd_env\[[^\]]*\bmarl\b", dev), dev
    assert re.search(r'^marl = \[.*"ray\[rllib\]', pyproject, re.M)
    try:
        requires = metadata.requires("ray") or []
        ray_version = metadata.version("ray")
    except metadata.PackageNotFoundError:
        pytest.skip("ray is not installed: its pin cannot be checked")
    pins = [re.match(r"gymnasium==([\d.]+)", r) for r in requires if 'extra == "rllib"' in r]
    pins = [m.group(1) for m in pins if m]
    assert pins, f"ray {ray_version} pins no gymnasium for its rllib extra any more: update the page"
    assert f"`ray[rllib]` (Ray {ray_version}) pins `gymnasium=={pins[0]}`" in text
