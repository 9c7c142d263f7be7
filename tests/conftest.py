"""Shared fixtures: ``fleet_factory`` starts real fleets and always stops them."""

from __future__ import annotations

import pytest

from tests.fleet_harness import FAST, Fleet, start_fleet


@pytest.fixture
def fleet_factory(tmp_path):
    """Start fleets; always stop them, assert exit 0 and that no process is left."""
    fleets: list[Fleet] = []

    def make(**kw) -> Fleet:
        f = start_fleet(tmp_path / f"run{len(fleets)}", kw.pop("mission", FAST), **kw)
        fleets.append(f)
        return f

    yield make
    for f in fleets:
        codes = f.stop()
        assert all(p.proc.poll() is not None for p in f.companions)
        assert f.sitl.proc.poll() is not None
        assert codes == [0] * len(codes), codes
