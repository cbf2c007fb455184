import os
from pathlib import Path

import pytest
from hypothesis import settings

ROOT = Path(__file__).resolve().parent.parent
CAMS = ROOT / "firmware_tables" / "cams"

settings.register_profile("ci", max_examples=60, deadline=None, derandomize=True)
settings.register_profile("dev", max_examples=60, deadline=None)
settings.load_profile("ci" if os.environ.get("CI") else "dev")


@pytest.fixture
def drrd():
    import ecam

    return ecam.load_cam(CAMS / "combination_drrd.toml")


@pytest.fixture
def msine():
    import ecam

    return ecam.load_cam(CAMS / "modified_sine.toml")
