"""Interoperability with an independent CANopen stack (issue 13, item 5): a CiA 402 master written
with the Rust crate canopen-rs (its own SDO client, NMT, PDO and EMCY codecs; no code shared
with python canopen) drives `ecam drive --interface udp_multicast` in another process, inside
a private network namespace with only loopback, so no frame leaves the machine.

The master (tests/drive_interop/canopen_rs_master) speaks python-can's udp_multicast wire
format itself. It sees the boot-up after an NMT reset, reads by SDO (expedited, segmented, an
abort), has a bad segmented download refused, writes the PDO mappings by SDO, enables CSP by
RPDO, streams targets and reads positions by TPDO, gets the following-error EMCY, resets the
fault and re-enables, sees the SYNC supervision fault (EMCY 0x8100), and stops the drive by NMT.

The master is built with cargo (crates from crates.io, pinned by its Cargo.lock; a few seconds
once the crates are cached, about 10 s with their download from crates.io); the test skips,
naming what is missing, without cargo, with a cargo too old for the lock file (before 1.78;
Debian 12's own is 0.66), without the crates and no registry, or without network namespaces.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from test_drive_network import SETUP, _namespace_unavailable

MASTER = Path(__file__).resolve().parent / "drive_interop" / "canopen_rs_master"
BINARY = MASTER / "target" / "debug" / "ecam-canopen-rs-master"
#: What cargo says when it cannot fetch a crate (no registry here): a reason to skip, not a failure.
_OFFLINE = ("failed to download", "failed to get", "Unable to update registry",
            "failed to query replaced source registry", "no matching package named")
STAGES = ("boot-up after NMT reset communication", "sdo: expedited and segmented upload",
          "segmented download refused: abort 0x08000020", "pdo mapping written by sdo",
          "operational, operation enabled in CSP", "streamed 300 targets", "emcy 0x8611",
          "fault reset and re-enabled", "sync lost: emcy 0x8100", "nmt stopped")


#: The oldest cargo that reads the master's Cargo.lock (lock file version 4, cargo 1.78); an
#: older one (Debian 12's cargo is 0.66, Rust 1.65) cannot build it at all.
MIN_CARGO = (1, 78)


def _cargo_too_old(version: str) -> str | None:
    """Why ``cargo --version``'s output names a cargo that cannot build the master, or None."""
    found = re.match(r"cargo (\d+)\.(\d+)", version)
    if found is None or (int(found[1]), int(found[2])) >= MIN_CARGO:
        return None
    return (f"cargo {found[1]}.{found[2]} is older than {MIN_CARGO[0]}.{MIN_CARGO[1]}, the "
            f"first that reads {MASTER.name}/Cargo.lock (lock file version 4; rustup installs a "
            "newer one)")


def _build_master() -> str | None:
    """Build the master; None, or why the test cannot run here."""
    if shutil.which("cargo") is None:
        return "cargo is not installed (rustup)"
    version = subprocess.run(["cargo", "--version"], capture_output=True, text=True, timeout=60)
    too_old = _cargo_too_old(version.stdout)
    if too_old:
        return too_old
    build = None
    for offline in (True, False):  # the crates cached from an earlier build, else the registry
        command = ["cargo", "build", "--locked", "--quiet"] + (["--offline"] if offline else [])
        build = subprocess.run(command, cwd=MASTER, capture_output=True, text=True, timeout=600,
                               env={**os.environ, "CARGO_TERM_COLOR": "never"})
        if build.returncode == 0:
            return None
    if any(sign in build.stderr for sign in _OFFLINE):
        return f"the crates of {MASTER.name} cannot be fetched: {build.stderr.strip().splitlines()[-1]}"
    pytest.fail(f"cargo build failed in {MASTER}:\n{build.stderr}")


def test_a_cargo_too_old_for_the_lock_file_is_a_reason_to_skip():
    assert _cargo_too_old("cargo 1.95.0 (f2d3ce0bd 2026-03-21)") is None
    assert _cargo_too_old("cargo 1.78.0 (54d8815d0 2024-03-26)") is None
    assert _cargo_too_old("cargo 1.77.2 (e52e36006 2024-03-26)").startswith("cargo 1.77 is older than 1.78")
    assert _cargo_too_old("cargo 0.66.0").startswith("cargo 0.66 is older than 1.78")


@pytest.mark.slow
def test_a_canopen_rs_master_drives_the_drive_over_udp_multicast():
    reason = _namespace_unavailable() or _build_master()
    if reason:
        pytest.skip(reason)
    # The drive starts first; the master waits for its heartbeat, then resets its communication
    # and sees the boot-up. The drive is stopped with SIGTERM once the master is done.
    script = (f'{SETUP} || exit 1; "$0" -m ecam.app drive --interface udp_multicast --node-id 3 & '
              'drive=$!; "$1" 3; status=$?; kill -TERM $drive; wait $drive; '
              'echo "drive exit $?"; exit $status')
    run = subprocess.run(["unshare", "-n", "sh", "-c", script, sys.executable, str(BINARY)],
                         capture_output=True, text=True, timeout=120)
    steps = [line for line in run.stdout.splitlines() if line.startswith("step:")]
    assert run.returncode == 0 and "\nok\n" in run.stdout, run.stdout + run.stderr
    for stage in STAGES:
        assert any(line.startswith(f"step: {stage}") for line in steps), (stage, run.stdout)
    assert run.stdout.strip().splitlines()[-1] == "drive exit 0", run.stdout
    print("\n".join(steps))
