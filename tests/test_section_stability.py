"""What a section's characteristic says at run time: interpolation, stabilising direction, the
force-limited feed, the expected chatter frequency."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _plans import characteristic

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


def _ch(**kw) -> Characteristic:
    c = characteristic(**kw)
    return Characteristic(c["feeds_mm_s"], c["margin_N_per_m"], c["force_N"])


def test_interpolation_is_linear_and_clamped():
    ch = _ch(boundary_mm_s=10.0)
    assert margin_at(ch, 10.0) == pytest.approx(0.0, abs=1e-6)
    assert margin_at(ch, 5.0) == pytest.approx(5e4)
    assert force_at(ch, 8.0) == pytest.approx(20 + 15 * 8)
    assert force_at(ch, 100.0) == pytest.approx(20 + 15 * 20)  # clamped at the last feed


@pytest.mark.parametrize("kw,feed,direction", [
    ({"boundary_mm_s": 10.0}, 8.0, -1),                    # margin falls with feed: slower
    ({"boundary_mm_s": 10.0, "rising": True}, 8.0, 1),     # margin rises with feed: faster
    ({"flat": True}, 8.0, 0),                              # flat: no direction
    ({"boundary_mm_s": 10.0}, 1.0, -1),                    # at the grid's first feed
    ({"boundary_mm_s": 10.0}, 20.0, -1),                   # at its last
])
def test_stabilising_direction(kw, feed, direction):
    d, rel = stabilising_direction(_ch(**kw), feed)
    assert d == direction
    assert (abs(rel) < FLAT_MARGIN_REL) == (direction == 0)


def test_a_nearly_flat_margin_has_no_direction():
    f = np.linspace(1, 20, 20)
    m = 1e4 * (1 + 1e-4 * f)  # 10 % feed change moves the margin by 1e-5 of its scale
    d, rel = stabilising_direction(Characteristic(f, m, 10 * f), 8.0)
    assert d == 0 and rel > 0


def test_feed_limit_for_force():
    ch = _ch()  # force 20 + 15 f
    assert feed_limit_for_force(ch, 140.0) == pytest.approx(8.0)
    assert feed_limit_for_force(ch, 1000.0) == math.inf
    assert feed_limit_for_force(ch, 10.0) == pytest.approx(1.0)  # even the lowest feed is over


def test_characteristic_of_sections():
    assert characteristic_of({"characteristic": None}) is None
    assert characteristic_of({"characteristic": {"feeds_mm_s": [1.0]}}) is None
    assert characteristic_of({"characteristic": characteristic()}) is not None
    unsorted = {"feeds_mm_s": [3.0, 1.0, 2.0], "margin_N_per_m": [3, 1, 2], "force_N": [30, 10, 20]}
    ch = characteristic_of({"characteristic": unsorted})
    assert list(ch.feeds_mm_s) == [1, 2, 3] and list(ch.force_N) == [10, 20, 30]


def test_chatter_frequency():
    assert chatter_frequency({"natural_frequency_hz": [9.0, 16.0]}, 11.0) == pytest.approx(12.0)
    assert chatter_frequency({"natural_frequency_hz": None}, 11.0) == 11.0
    assert chatter_frequency({}, 11.0) == 11.0
    assert chatter_frequency({"natural_frequency_hz": [0.0, 5.0]}, 11.0) == 11.0
