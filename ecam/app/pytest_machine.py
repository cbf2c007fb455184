"""pytest items of a machine file, for the plugin's ``--ecam-scenes DIR``
(:mod:`ecam.app.pytest_plugin`): one test per axis, ``<file>.toml::<axis>``, failing with that
axis's failed check lines, and one for the machine's own checks, ``<file>.toml::machine`` (bus
load, faults). The machine runs once, when the first of its items runs; every item reads that
run. A machine file that does not load is one item, ``machine``, failing with the one-line
error. Only pytest is imported at module level (the plugin is loaded into every pytest run)."""

from __future__ import annotations

import time

import pytest


class CheckFailure(AssertionError):
    """Checks of an axis (or of the machine) failed; the message is their lines."""

    def __init__(self, what: str, checks: list, total: int) -> None:
        lines = [c.line() for c in checks]
        lines.append(f"{what}: {len(checks)} of {total} checks failed")
        super().__init__("\n".join(lines))


def machine_file(parent, path, results_key):
    """The collector of the machine file ``path``; ``results_key`` is the plugin's stash key of
    the runs its ``--ecam-html`` page shows (each axis is shown as a scene)."""
    node = MachineFile.from_parent(parent, path=path)
    node.results_key = results_key
    return node


class MachineFile(pytest.File):
    """A machine file: an item per axis and one for the machine; it runs once."""

    results_key = None

    def collect(self):
        from ecam.errors import EcamError
        from hil_sim.machine import load_machine

        self._outcome = None
        try:
            self.machine = load_machine(self.path)
        except EcamError as exc:
            self.machine, self._error = None, exc
            yield MachineItem.from_parent(self, name="machine")
            return
        yield MachineItem.from_parent(self, name="machine")
        for axis in self.machine.axes:
            yield AxisItem.from_parent(self, name=axis.name)

    def outcome(self):
        """The machine's report, run on first use (an EcamError raised as is)."""
        if self.machine is None:
            raise self._error
        if self._outcome is None:
            from hil_sim.rig.machine_run import run_machine

            start = time.perf_counter()
            report = run_machine(self.machine)
            seconds = time.perf_counter() - start
            self._outcome = report
            results = self.config.stash.get(self.results_key, None) \
                if self.results_key is not None else None
            if results is not None:
                scenes = {a.name: a for a in self.machine.axes}
                results.extend((scenes[a.scene], a, seconds) for a in report.axes)
        return self._outcome


class _Item(pytest.Item):
    def repr_failure(self, excinfo, style=None):
        from ecam.errors import EcamError

        if isinstance(excinfo.value, (CheckFailure, EcamError)):
            return str(excinfo.value)
        return super().repr_failure(excinfo, style=style)


class MachineItem(_Item):
    """The machine's own checks (bus load, faults); the whole text report attached."""

    def runtest(self) -> None:
        report = self.parent.outcome()
        self.add_report_section("call", "ecam report", report.to_text())
        failed = [c for c in report.machine_checks if not c.passed]
        if failed:
            raise CheckFailure(f"machine {report.machine}", failed, len(report.machine_checks))

    def reportinfo(self):
        return self.path, None, f"machine {self.path.stem}"


class AxisItem(_Item):
    """One axis of the machine: its checks, as a scene's."""

    def runtest(self) -> None:
        report = self.parent.outcome().axis(self.name)
        self.add_report_section("call", "ecam report", report.to_text())
        if not report.passed:
            raise CheckFailure(f"axis {self.name}", report.failed, len(report.checks))

    def reportinfo(self):
        return self.path, None, f"axis {self.name} of {self.path.stem}"
