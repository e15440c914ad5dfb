"""What a section's characteristic says at run time: interpolation, stabilising direction, the
force-limited feed, the expected chatter frequency."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _plans import characteristic

from planner.plan_file import PlanSection, SectionCharacteristic
from planner.supervisor.characteristic import (
    FLAT_MARGIN_REL,
    Characteristic,
    characteristic_of,
    chatter_frequency,
    feed_limit_for_force,
    force_at,
    margin_at,
    stabilising_direction,
)

MM = 1e-3  # mm/s → m/s


def _ch(**kw) -> Characteristic:
    c = characteristic(**kw)
    return Characteristic(np.asarray(c["feeds_mm_s"]) * MM, c["margin_N_per_m"], c["force_N"])


def _section(char: dict | None = None, kind: str = "cut", nf=None) -> PlanSection:
    return PlanSection(index=0, kind=kind, sample_start=0, sample_stop=2, s_start=0.0, s_end=0.1,
                       feed=8 * MM, binding="chatter", natural_frequencies=nf,
                       characteristic=None if char is None else SectionCharacteristic.from_json(char))


def test_interpolation_is_linear_and_clamped():
    ch = _ch(boundary_mm_s=10.0)
    assert margin_at(ch, 10 * MM) == pytest.approx(0.0, abs=1e-6)
    assert margin_at(ch, 5 * MM) == pytest.approx(5e4)
    assert force_at(ch, 8 * MM) == pytest.approx(20 + 15 * 8)
    assert force_at(ch, 100 * MM) == pytest.approx(20 + 15 * 20)  # clamped at the last feed


@pytest.mark.parametrize("kw,feed,direction", [
    ({"boundary_mm_s": 10.0}, 8.0, -1),                    # margin falls with feed: slower
    ({"boundary_mm_s": 10.0, "rising": True}, 8.0, 1),     # margin rises with feed: faster
    ({"flat": True}, 8.0, 0),                              # flat: no direction
    ({"boundary_mm_s": 10.0}, 1.0, -1),                    # at the grid's first feed
    ({"boundary_mm_s": 10.0}, 20.0, -1),                   # at its last
])
def test_stabilising_direction(kw, feed, direction):
    d, rel = stabilising_direction(_ch(**kw), feed * MM)
    assert d == direction
    assert (abs(rel) < FLAT_MARGIN_REL) == (direction == 0)


def test_a_nearly_flat_margin_has_no_direction():
    f = np.linspace(1, 20, 20)
    m = 1e4 * (1 + 1e-4 * f)  # 10 % feed change moves the margin by 1e-5 of its scale
    d, rel = stabilising_direction(Characteristic(f * MM, m, 10 * f), 8 * MM)
    assert d == 0 and rel > 0


def test_feed_limit_for_force():
    ch = _ch()  # force 20 + 15 f
    assert feed_limit_for_force(ch, 140.0) == pytest.approx(8 * MM)
    assert feed_limit_for_force(ch, 1000.0) == math.inf
    assert feed_limit_for_force(ch, 10.0) == pytest.approx(1 * MM)  # even the lowest feed is over


def test_characteristic_of_sections():
    assert characteristic_of(_section(None)) is None
    assert characteristic_of(_section({"feeds_mm_s": [1.0], "margin_N_per_m": [1.0],
                                       "force_N": [1.0]})) is None          # one feed: none
    assert characteristic_of(_section(characteristic())) is not None
    assert characteristic_of(_section(characteristic(), kind="air")) is None
    unsorted = {"feeds_mm_s": [3.0, 1.0, 2.0], "margin_N_per_m": [3, 1, 2], "force_N": [30, 10, 20]}
    ch = characteristic_of(_section(unsorted))
    assert list(ch.feeds / MM) == pytest.approx([1, 2, 3]) and list(ch.force) == [10, 20, 30]


def test_a_malformed_characteristic_is_none():
    bad = {"feeds_mm_s": [1.0, 2.0], "margin_N_per_m": [1.0], "force_N": [1.0, 2.0]}
    sec = PlanSection.from_json({"index": 1, "kind": "cut", "sample_start": 0, "sample_stop": 2,
                                 "s_start_m": 0.0, "s_end_m": 0.1, "feed_mm_s": 8.0,
                                 "binding": "chatter", "characteristic": bad})
    assert sec.characteristic is None and characteristic_of(sec) is None  # dropped when read


def test_chatter_frequency():
    assert chatter_frequency(_section(nf=(9.0, 16.0)), 11.0) == pytest.approx(12.0)
    assert chatter_frequency(_section(nf=None), 11.0) == 11.0
    assert chatter_frequency(_section(nf=(0.0, 5.0)), 11.0) == 11.0
