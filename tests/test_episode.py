"""How a chatter episode's moves are judged (planner.supervisor.episode.judge): a raise that feeds
the chatter is reversed, one that turns it is not; chatter the floor does not stop is escalated."""

from __future__ import annotations

import pytest

from planner.supervisor.episode import (
    ESCALATE_PERIODS,
    GROWTH_RATIO,
    NOT_FALLING_RATIO,
    Episode,
    judge,
)

D, TD, FLOOR = 0.18, 0.27, 20.0


def _judge_series(direction, envelopes, applied=50.0, alarm=True, dt=0.004):
    """Feed ``envelopes`` (one per 4 ms step from the episode's start); return (step, verdict)
    of the first verdict, or None."""
    ep = Episode(0.0, 0.0, 0, applied, direction, base=applied)
    for k, env in enumerate(envelopes):
        v = judge(ep, k * dt, env, alarm, applied, FLOOR, D, TD)
        if v is not None:
            return k * dt, v
    return None


def _ramp(t_s, f, dt=0.004):
    return [f(k * dt) for k in range(int(t_s / dt))]


@pytest.mark.parametrize("shape,verdict,by_s", [
    # saturated chatter: the band stays at its peak -> reversed at the decision period
    (lambda t: 800.0 * min(1.0, t / 0.1), "has not fallen", TD),
    # growing on after the band delay -> reversed as soon as it is 1.25 x its value at D
    (lambda t: 100.0 * (1.0 + 20.0 * t), "grew", D + (GROWTH_RATIO - 1) * (1 + 20 * D) / 20 + 0.01),
])
def test_a_raise_that_does_not_turn_the_chatter_is_reversed(shape, verdict, by_s):
    got = _judge_series(+1, _ramp(0.5, shape))
    assert got is not None
    t, (what, why) = got
    assert what == "reverse" and verdict in why
    assert t <= by_s + 0.004   # the first step at or after it


def test_a_raise_whose_band_falls_after_the_delay_is_not_reversed():
    # peak at 0.12 s (the band's lag), then down: what a raise that works looks like
    env = _ramp(0.6, lambda t: 800.0 * min(t / 0.12, max(0.05, 1.0 - 4.0 * (t - 0.12))))
    assert _judge_series(+1, env) is None


def test_chatter_at_the_floor_is_escalated_when_it_does_not_fall():
    t, (what, why) = _judge_series(-1, [700.0] * 100, applied=FLOOR + 0.5)
    assert what == "escalate" and "floor" in why and t == pytest.approx(TD, abs=0.004)


def test_chatter_falling_at_the_floor_gets_time_but_not_forever():
    # falling steadily but slowly, always over the limit: escalated after ESCALATE_PERIODS
    env = _ramp(2.0, lambda t: 800.0 * (NOT_FALLING_RATIO - 0.1) ** (t / TD))
    t, (what, why) = _judge_series(-1, env, applied=FLOOR)
    assert what == "escalate" and f"{ESCALATE_PERIODS} decision periods" in why
    assert t == pytest.approx(ESCALATE_PERIODS * TD, abs=0.004)


def test_no_verdict_above_the_floor_or_without_an_alarm():
    assert _judge_series(-1, [700.0] * 300, applied=FLOOR + 5.0) is None
    assert _judge_series(-1, [700.0] * 300, applied=FLOOR, alarm=False) is None
