"""sim.env.planner: ACC, flicker hold, lane-change gaps on synthetic observations; closed-loop episodes on
tracks (curve-single, cut-in) without collision; lane keeping at low speed; a motorcycle between lanes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.env import COL, COLUMNS, NO_LABEL, TrackedRoadEnv
from sim.env.planner import Planner, PlannerConfig, planner_for

LANES = (-1.75, 1.75)


def obs_with(*rows: tuple[float, float, float, int], ego_n: float = -1.75,
             ego_v: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    """An observation and its row labels (the env's ``info["labels"]``): the ego on lane 0 and rows
    ``(ds, n, v, label)`` of 4.8 x 2 m cars."""
    obs = np.zeros((1 + 8, len(COLUMNS)), dtype=np.float32)
    labels = np.full(1 + 8, NO_LABEL, dtype=np.int64)
    obs[0, [COL["present"], COL["n"], COL["v"], COL["length"], COL["width"]]] = [1, ego_n, ego_v, 4.8, 2.0]
    for k, (ds, n, v, label) in enumerate(rows, start=1):
        obs[k, [COL["present"], COL["ds"], COL["n"], COL["v"], COL["length"], COL["width"]]] = [1, ds, n, v, 4.8, 2.0]
        labels[k] = label
    return obs, labels


def accel(planner: Planner, action: np.ndarray) -> float:
    lo, hi = planner.config.accel_range
    return lo + (float(action[0]) + 1.0) * 0.5 * (hi - lo)


def test_acc_brakes_for_a_slow_lead_in_lane_and_ignores_the_next_lane():
    p = Planner(PlannerConfig(lane_centers=LANES, lane_changes=False))
    a_free = accel(p, p.act(*obs_with(ego_v=20.0)))
    assert a_free == pytest.approx(0.0, abs=1e-5)  # at the set speed (the first observation's), no lead
    p.reset()
    p.act(*obs_with(ego_v=20.0))
    a_next_lane = accel(p, p.act(*obs_with((20.0, 1.75, 5.0, 7))))
    assert a_next_lane == pytest.approx(0.0, abs=1e-5) and p.decision.lead_label is None
    a_lead = accel(p, p.act(*obs_with((20.0, -1.6, 5.0, 7))))
    # IDM: s* = 4 + 20 * 1.5 + 20 * 15 / (2 sqrt(1.5 * 2.5)); gap = 20 - 4.8 = 15.2 m -> clipped to -8
    assert a_lead == pytest.approx(-8.0)
    assert p.decision.lead_label == 7 and p.decision.lead_gap == pytest.approx(15.2, abs=1e-4)
    p.act(*obs_with((80.0, -1.75, 20.0, 7)))
    gap = 80.0 - 4.8
    s_star = 4.0 + 20.0 * 1.5
    assert p.decision.accel == pytest.approx(-1.5 * (s_star / gap) ** 2)


def test_flickering_lead_is_held_then_forgotten():
    p = Planner(PlannerConfig(lane_centers=LANES, lane_changes=False, lead_hold_s=0.6))
    p.act(*obs_with((30.0, -1.75, 15.0, 3)))
    assert p.decision.lead_source == "row"
    p.act(*obs_with())  # the track flickers out
    assert p.decision.lead_label == 3 and p.decision.lead_source == "held"
    assert p.decision.lead_ds == pytest.approx(30.0 + (15.0 - 20.0) * 0.2)  # predicted at its speed
    assert p.decision.accel < 0
    for _ in range(3):
        p.act(*obs_with())
    assert p.decision.lead_label is None  # older than lead_hold_s


def test_lane_change_only_into_a_safe_gap():
    slow_lead = (58.0, -1.75, 14.0, 1)  # within the 60 m lookahead, slower than the 18 m/s set speed
    p = Planner(PlannerConfig(lane_centers=LANES))
    p.act(*obs_with(slow_lead, (-6.0, 1.75, 21.0, 2), ego_v=18.0))  # a car alongside-behind in lane 1
    p.act(*obs_with(slow_lead, (-6.0, 1.75, 21.0, 2), ego_v=18.0))
    assert p.decision.target_lane == 0
    q = Planner(PlannerConfig(lane_centers=LANES))
    q.act(*obs_with(slow_lead, (-40.0, 1.75, 21.0, 2), ego_v=18.0))
    assert q.decision.target_lane == 1 and q.decision.changing
    assert q.decision.accel > -2.5  # not an emergency
    left = Planner(PlannerConfig(lane_centers=LANES))  # in the leftmost lane the only free lane is lane 0
    left.act(*obs_with((58.0, 1.75, 14.0, 1), ego_n=1.75, ego_v=18.0))
    assert left.decision.target_lane == 0
    braking = Planner(PlannerConfig(lane_centers=LANES))  # braking hard for the lead: stay in the lane
    braking.act(*obs_with((25.0, -1.75, 12.0, 1), (-40.0, 1.75, 21.0, 2), ego_v=18.0))
    assert braking.decision.accel < -2.5 and braking.decision.target_lane == 0


def test_planner_needs_one_label_per_row():
    p = Planner(PlannerConfig(lane_centers=LANES))
    obs, labels = obs_with((30.0, -1.75, 15.0, 3))
    with pytest.raises(ValueError, match="labels"):
        p.act(obs, labels[:2])


def test_planner_needs_the_continuous_action():
    env = TrackedRoadEnv({"scenario": "curve-single", "duration": 0.4, "perception": "truth"})
    _, info = env.reset(seed=0)
    with pytest.raises(ValueError, match="ContinuousAction"):
        planner_for(env.settings, info["lane_centers"])


def drive(scenario: str, duration: float, seed: int = 0) -> tuple[TrackedRoadEnv, Planner, list[float], list]:
    env = TrackedRoadEnv({"scenario": scenario, "action": "ContinuousAction", "perception": "tracks",
                          "duration": duration})
    obs, info = env.reset(seed=seed)
    planner = planner_for(env.settings, info["lane_centers"])
    lateral, decisions = [], []
    done = False
    while not done:
        action = planner.act(obs, info["labels"])
        decisions.append(planner.decision)
        obs, _, terminated, truncated, info = env.step(action)
        lane = planner.decision.target_lane
        lateral.append(abs(obs[0, COL["n"]] - info["lane_centers"][lane]))
        done = terminated or truncated
    return env, planner, lateral, decisions


def test_planner_keeps_its_lane_on_curve_single_with_tracks():
    env, _, lateral, decisions = drive("curve-single", 6.0)
    assert not env.vehicle.crashed and env.world.collisions == []
    assert env.sim_time == pytest.approx(6.0)
    assert max(lateral) < 0.3  # on the R 150 m curve
    assert abs(env.world.ego_state().v - 20.0) < 0.5
    assert all(d.lead_label is None for d in decisions)  # the car is in the next lane


def test_lane_keeping_is_stable_at_walking_and_town_speeds():
    """On a straight road at 3-8 m/s the lateral cascade settles (the course's slip is solved for the
    new command; taking the last command's slip made the heading loop alternate and grow below ~8 m/s)."""
    for speed in (3.0, 5.0, 8.0):
        cfg = PlannerConfig(lane_centers=LANES, lane_changes=False)
        p = Planner(cfg)
        # a kinematic bicycle (l_r 2.4 m) driven by the planner at 5 Hz, starting 0.3 m off the lane centre
        n, xi, v, l_r = -1.45, 0.0, speed, 2.4
        offsets = []
        for _ in range(100):
            obs, labels = obs_with(ego_n=n, ego_v=v)
            yaw_rate = v * math.sin(math.atan(0.5 * math.tan(p._steer))) / l_r
            obs[0, COL["xi"]], obs[0, COL["xi_dot"]] = xi, yaw_rate
            action = p.act(obs, labels)
            lo, hi = cfg.steering_range
            steer = lo + (float(action[1]) + 1.0) * 0.5 * (hi - lo)
            beta = math.atan(0.5 * math.tan(steer))
            for _ in range(4):  # the world's 0.05 s steps
                n += v * math.sin(xi + beta) * 0.05
                xi += v * math.sin(beta) / l_r * 0.05
            offsets.append(abs(n - LANES[0]))
        assert max(offsets[-25:]) < 0.02, (speed, offsets[-5:])  # settled on the lane centre
        assert max(offsets) < 0.35  # no overshoot beyond the start


def test_while_changing_lanes_a_standing_vehicle_in_the_lane_being_left_still_holds_the_ego_back():
    """Mid-change (target lane 1, still in lane 0): a faster car 25 m ahead in lane 1 and a standing car
    45 m ahead in lane 0. The lead is the one asking for the lower acceleration, the standing car, not
    the nearer one."""
    p = Planner(PlannerConfig(lane_centers=LANES, set_speed=20.0))
    p.act(*obs_with(ego_v=20.0))
    p._target = 1
    obs, labels = obs_with((25.0, 1.75, 24.0, 3), (45.0, -1.75, 0.0, 4), ego_n=-1.2, ego_v=20.0)
    p.act(obs, labels)
    assert p.decision.lead_label == 4 and p.decision.accel == pytest.approx(-8.0)
    p2 = Planner(PlannerConfig(lane_centers=LANES, set_speed=20.0))
    p2.act(*obs_with(ego_v=20.0))
    p2._target = 1
    obs, labels = obs_with((25.0, 1.75, 15.0, 3), (80.0, -1.75, 19.0, 4), ego_n=-1.2, ego_v=20.0)
    p2.act(obs, labels)
    assert p2.decision.lead_label == 3  # the slower, nearer car in the target lane asks for less


def test_a_vehicle_the_egos_body_still_overlaps_is_a_lead_after_its_centre_crossed_the_line():
    """The ego's centre has crossed into lane 1 (n = 0.1 m), its right side still over lane 0: a car
    standing 40 m ahead in lane 0 is still in its path."""
    p = Planner(PlannerConfig(lane_centers=LANES, set_speed=20.0))
    p.act(*obs_with(ego_v=20.0))
    p._target = 1
    p.act(*obs_with((40.0, -1.75, 0.0, 4), ego_n=0.1, ego_v=15.0))
    assert p.lane_of(0.1) == 1 and p.decision.lead_label == 4 and p.decision.accel < -5.0
    p.act(*obs_with((40.0, -1.75, 0.0, 4), ego_n=1.0, ego_v=15.0))  # 2.75 m across: passed
    assert p.decision.lead_label is None


def test_a_motorcycle_on_the_lane_line_blocks_a_lane_change_into_either_lane():
    """A 0.8 m motorcycle riding on the line between lanes 0 and 1, 5 m behind and faster: the lane it
    straddles is not free (its rectangle reaches into it), although its centre is outside the ego's path."""
    p = Planner(PlannerConfig(lane_centers=LANES, set_speed=20.0))
    obs, labels = obs_with((55.0, -1.75, 16.0, 5), (-8.0, 0.0, 26.0, 9), ego_v=20.0)
    obs[2, COL["length"]], obs[2, COL["width"]] = 2.2, 0.8
    p.act(obs, labels)
    assert p.decision.target_lane == 0 and not p.decision.changing  # blocked: the motorcycle is in lane 1 too
    assert p.decision.lead_label == 5  # the motorcycle is not the lead (centre 1.75 m off the ego's lane)
    p2 = Planner(PlannerConfig(lane_centers=LANES, set_speed=20.0))
    obs2, labels2 = obs_with((55.0, -1.75, 16.0, 5), ego_v=20.0)
    p2.act(obs2, labels2)
    assert p2.decision.target_lane == 1  # without it the change is taken


def test_planner_handles_the_cut_in_with_tracks():
    env, _, _, decisions = drive("cut-in", 16.0)
    assert not env.vehicle.crashed and env.world.collisions == []
    # the cut-in car (truth id 1) became the lead and the planner braked for it
    braking = [d for d in decisions if d.lead_label is not None and d.accel < -0.5]
    assert braking
    assert min(d.lead_gap for d in decisions) > 5.0


def test_the_planner_changes_lanes_only_into_driving_lanes_of_its_own_direction():
    """On a two-way road (lane 0 along s, lane 1 against) with a parking lane on the right, a planner
    behind a slow lead has nowhere to go: no lane change into oncoming traffic or the parking lane; with
    the directions unknown it would take the oncoming lane."""
    from sim.env.planner import Planner, PlannerConfig

    cfg = dict(lane_centers=(-4.0, -1.5, 1.5), set_speed=20.0, lane_changes=True)
    two_way = Planner(PlannerConfig(**cfg, lane_directions=(1, 1, -1), lane_kinds=("parking", "driving", "driving")))
    assert not two_way._may_enter(1, 2) and not two_way._may_enter(1, 0) and two_way._may_enter(1, 1)
    blind = Planner(PlannerConfig(**cfg))
    assert blind._may_enter(1, 2) and blind._may_enter(1, 0)
    with pytest.raises(ValueError, match="lane_directions"):
        PlannerConfig(**cfg, lane_directions=(1, 0, 1))


def test_lane_centres_given_per_step_a_lane_that_ends_and_one_that_is_absent():
    """``act(..., lane_centers=...)``: a lane absent at the ego's ``s`` (NaN) is never entered, and when the
    target lane ends the ego steers for the present lane nearest to it."""
    p = Planner(PlannerConfig(lane_centers=(-5.25, -1.75, 1.75)))
    slow = (58.0, -1.75, 14.0, 7)  # a slow lead in the ego's lane 1 (ego at n = -1.75), within the lookahead
    p.act(*obs_with(slow, ego_v=18.0), lane_centers=(math.nan, -1.75, math.nan))
    assert p.decision.target_lane == 1 and not p.decision.changing  # no lane to change into: it follows
    p.act(*obs_with(slow, ego_v=18.0), lane_centers=(math.nan, -1.75, 1.75))
    assert p.decision.target_lane == 2 and p.decision.changing  # lane 2 is there now: it changes
    # the ego in lane 0 (an auxiliary lane), which ends: the target becomes lane 1, the nearest present one
    q = Planner(PlannerConfig(lane_centers=(-5.25, -1.75, 1.75)))
    q.act(*obs_with(ego_n=-5.25))
    assert q.decision.target_lane == 0
    q.act(*obs_with(ego_n=-5.25), lane_centers=(math.nan, -1.75, 1.75))
    assert q.decision.target_lane == 1 and q.decision.changing
    assert q.lane_of(-5.25) == 1 and np.isnan(q.centers[0])
    with pytest.raises(ValueError, match="lane_centers has 2 entries"):
        q.act(*obs_with(), lane_centers=(0.0, 1.0))
    with pytest.raises(ValueError, match="needs one present"):
        q.act(*obs_with(), lane_centers=(math.nan,) * 3)


def test_a_goal_lane_draws_lane_changes_toward_it_when_the_gap_allows():
    """``goal_lane``: from lane 0 toward lane 2 one lane at a time, without a slow lead; not into a gap a
    car alongside closes; no change around a slow lead away from the goal lane."""
    three = (-1.75, 1.75, 5.25)
    p = Planner(PlannerConfig(lane_centers=three, goal_lane=2))
    p.act(*obs_with(ego_v=18.0))
    assert p.decision.target_lane == 1 and p.decision.changing  # free road: toward the goal lane
    q = Planner(PlannerConfig(lane_centers=three, goal_lane=2))
    q.act(*obs_with((-6.0, 1.75, 21.0, 2), ego_v=18.0))  # a car alongside-behind in lane 1
    assert q.decision.target_lane == 0
    stay = Planner(PlannerConfig(lane_centers=three, goal_lane=0))  # in the goal lane behind a slow lead
    stay.act(*obs_with((58.0, -1.75, 14.0, 1), ego_v=18.0))
    assert stay.decision.target_lane == 0 and not stay.decision.changing
    with pytest.raises(ValueError, match="goal_lane = 3: must be a lane, 0..2"):
        PlannerConfig(lane_centers=three, goal_lane=3)
