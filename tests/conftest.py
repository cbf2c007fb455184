from pathlib import Path

import pytest
from hypothesis import settings

ROOT = Path(__file__).resolve().parent.parent
CAMS = ROOT / "firmware_tables" / "cams"

# One profile, with or without CI set: the same examples everywhere, so a failure seen in CI is
# the failure seen on a developer's machine.
settings.register_profile("ecam", max_examples=60, deadline=None, derandomize=True)
settings.load_profile("ecam")


@pytest.fixture
def drrd():
    import ecam

    return ecam.load_cam(CAMS / "combination_drrd.toml")


@pytest.fixture
def msine():
    import ecam

    return ecam.load_cam(CAMS / "modified_sine.toml")
