"""eot/TrackedRoad-v0 (sim.env): gymnasium API, registration (max_episode_steps), determinism, vector
env, observation layout, bounds and labels, config errors, actions, reward, rendering. Episodes are
kept to a few simulated seconds."""

from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import sim  # noqa: F401  (registers the env)
from sim.env import COL, COLUMNS, NO_LABEL, ConfigError, EnvConfig, TrackedRoadEnv
from sim.env.observation import denormalize, limits, observation_space, scales

IDLE = 1  # meta-action index (0 LANE_LEFT, 1 IDLE, 2 LANE_RIGHT, 3 FASTER, 4 SLOWER)


def make(**config) -> TrackedRoadEnv:
    config.setdefault("duration", 3.0)
    return TrackedRoadEnv(config)


def test_check_env_passes():
    env = make(scenario="cut-in", duration=2.0)
    check_env(env, skip_render_check=True)
    env.close()


def test_registered_and_reachable_from_a_fresh_interpreter():
    assert "eot/TrackedRoad-v0" in gym.registry
    code = (
        "import gymnasium as gym\n"
        "env = gym.make('sim:eot/TrackedRoad-v0', config={'duration': 0.4, 'perception': 'truth'})\n"
        "obs, info = env.reset(seed=1)\n"
        "print(obs.shape, type(env.unwrapped).__name__)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "(11, 10) TrackedRoadEnv"


def test_registered_max_episode_steps_is_the_default_episode():
    spec = gym.spec("eot/TrackedRoad-v0")
    assert spec.max_episode_steps == sim.ENV_MAX_EPISODE_STEPS == 100
    assert EnvConfig().episode_steps() == 100  # curve-single's 20 s at 5 Hz
    assert EnvConfig(duration=3.0).episode_steps() == 15
    assert EnvConfig(scenario="circuit").episode_steps() == 400  # longer: pass it to gym.make
    env = gym.make("eot/TrackedRoad-v0", config={"perception": "truth", "duration": 0.4})
    assert env.spec.max_episode_steps == 100 and env.unwrapped.max_episode_steps == 2
    env.close()
    env = gym.make("eot/TrackedRoad-v0", config={"perception": "truth", "duration": 0.4}, max_episode_steps=1)
    env.reset(seed=0)
    assert env.step(IDLE)[3]  # the TimeLimit truncates after one step
    env.close()


def test_reset_with_a_seed_is_deterministic_and_seeds_differ():
    env = make(scenario="random-road", duration=1.0)
    runs = []
    for seed in (4, 4, 5):
        obs, _ = env.reset(seed=seed)
        trace = [obs]
        for _ in range(4):
            obs, *_ = env.step(IDLE)
            trace.append(obs)
        runs.append((np.stack(trace), env.world.road.length))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    assert runs[0][1] == runs[1][1]
    assert runs[0][1] != runs[2][1]  # the generator drew another road for another seed
    # reset() without a seed draws the episode seed from np_random: reproducible after a seeded reset
    env.reset(seed=9)
    a = env.reset()[1]["episode_seed"]
    env.reset(seed=9)
    assert env.reset()[1]["episode_seed"] == a


def test_async_vector_env_steps():
    envs = gym.make_vec("eot/TrackedRoad-v0", num_envs=2, vectorization_mode="async",
                        config={"scenario": "cut-in", "duration": 1.0, "perception": "truth"})
    try:
        obs, info = envs.reset(seed=[0, 1])
        assert obs.shape == (2, 11, 10) and obs.dtype == np.float32
        for _ in range(3):
            obs, reward, terminated, truncated, info = envs.step(np.array([IDLE, 3]))
        assert obs.shape == (2, 11, 10)
        assert np.asarray(info["labels"]).shape == (2, 11)
        assert reward.shape == (2,) and np.all((reward >= 0) & (reward <= 1))
        assert obs[0, 0, COL["present"]] == 1.0 and obs[1, 0, COL["present"]] == 1.0
    finally:
        envs.close()


def test_tracks_observation_is_within_the_tracker_error_of_truth():
    tracks = make(scenario="curve-single", perception="tracks", duration=3.0)
    truth = make(scenario="curve-single", perception="truth", duration=3.0)
    obs_k, _ = tracks.reset(seed=2)
    obs_t, _ = truth.reset(seed=2)
    for _ in range(15):  # 3 s: the tracker confirms the car ahead in the next lane
        obs_k, _, _, _, info_k = tracks.step(IDLE)
        obs_t, _, _, _, info_t = truth.step(IDLE)
    assert obs_k.shape == obs_t.shape == (11, len(COLUMNS))  # the same layout
    np.testing.assert_array_equal(obs_k[0], obs_t[0])  # the ego row is odometry in both
    rows_t = obs_t[1:][obs_t[1:, 0] > 0]
    rows_k = obs_k[1:][obs_k[1:, 0] > 0]
    assert len(rows_t) == 1 and info_t["labels"].tolist() == [NO_LABEL, 1] + [NO_LABEL] * 9  # vehicle id 1
    assert len(rows_k) == 1 and info_k["labels"][1] == tracks.tracks[0].label and info_k["labels"][0] == NO_LABEL
    t, k = rows_t[0], rows_k[0]
    assert t[COL["sigma_s"]] == 0 and t[COL["sigma_n"]] == 0
    assert 0 < k[COL["sigma_s"]] < 1.0 and 0 < k[COL["sigma_n"]] < 1.0
    assert abs(k[COL["ds"]] - t[COL["ds"]]) <= 3 * k[COL["sigma_s"]] + 0.3
    assert abs(k[COL["n"]] - t[COL["n"]]) <= 3 * k[COL["sigma_n"]] + 0.2
    assert abs(k[COL["v"]] - t[COL["v"]]) < 1.0
    assert abs(k[COL["length"]] - t[COL["length"]]) < 1.0 and abs(k[COL["width"]] - t[COL["width"]]) < 0.5
    # the truth row is the world's vehicle in road coordinates relative to the ego
    ego = truth.world.ego_state()
    car = truth.world.states()[1]
    assert t[COL["ds"]] == pytest.approx(car.s - ego.s, abs=1e-4)
    assert t[COL["n"]] == pytest.approx(car.n, abs=1e-5) and car.lane == 1


def test_normalised_observation_is_scaled_and_in_the_box():
    raw = make(perception="truth", duration=1.0)
    norm = make(perception="truth", duration=1.0, normalize=True)
    a, _ = raw.reset(seed=0)
    b, _ = norm.reset(seed=0)
    assert raw.observation_space.contains(a) and norm.observation_space.contains(b)
    assert b[0, COL["v"]] == pytest.approx(a[0, COL["v"]] / scales()["v"])
    np.testing.assert_allclose(denormalize(b), a, atol=1e-5)
    assert norm.observation_space.low.min() == -1.0 and norm.observation_space.high.max() == 1.0


def test_observation_bounds_are_physical_and_finite():
    assert COLUMNS == ("present", "ds", "n", "v", "xi", "xi_dot", "length", "width", "sigma_s", "sigma_n")
    assert "label" not in COLUMNS  # an identity, not a feature: info["labels"]
    env = make(perception="tracks", duration=1.0)
    space = env.observation_space
    assert space.shape == (11, 10) and np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))
    assert np.all(space.low < space.high) and np.abs(np.concatenate([space.low, space.high])).max() <= 200.0
    row = dict(zip(COLUMNS, zip(space.low[0], space.high[0])))
    assert row["ds"] == (-200.0, 200.0)  # twice the lidar's 100 m range
    assert row["n"] == (-20.0, 20.0) and row["v"] == (0.0, 50.0)
    assert row["xi"] == pytest.approx((-np.pi, np.pi)) and row["xi_dot"] == (-2.0, 2.0)
    assert row["length"] == (0.0, 25.0) and row["width"] == (0.0, 4.0)
    assert row["sigma_s"] == row["sigma_n"] == (0.0, 10.0) and row["present"] == (0.0, 1.0)
    assert limits(50.0)["ds"] == (-100.0, 100.0)  # the scenario's lidar range sets the ds bound
    assert observation_space(3, False, 50.0).shape == (4, 10)
    # truth and tracks share the layout and the box
    assert make(perception="truth", duration=1.0).observation_space == space
    obs, info = env.reset(seed=0)
    assert space.contains(obs) and info["labels"].dtype == np.int64 and info["labels"].shape == (11,)
    assert np.all(info["labels"][obs[:, COL["present"]] == 0] == NO_LABEL) and info["labels"][0] == NO_LABEL


def test_bad_config_keys_and_values_are_named():
    with pytest.raises(ConfigError, match=r"unknown config key 'polcy_frequency'.*allowed keys: .*policy_frequency"):
        TrackedRoadEnv({"polcy_frequency": 5})
    with pytest.raises(ConfigError, match=r"'max_tracks' = 0"):
        TrackedRoadEnv({"max_tracks": 0})
    with pytest.raises(ConfigError, match=r"'perception' = 'lidar'"):
        gym.make("eot/TrackedRoad-v0", config={"perception": "lidar"})
    with pytest.raises(ConfigError, match=r"'policy_frequency' = 3.*lidar rate"):
        TrackedRoadEnv({"policy_frequency": 3})
    with pytest.raises(ConfigError, match=r"'scenario' = 'no-such-road'"):
        TrackedRoadEnv({"scenario": "no-such-road"})
    with pytest.raises(ConfigError, match=r"'observation'.*perception"):
        TrackedRoadEnv({"observation": {"type": "Kinematics"}})
    # highway-env's spelling of the action is accepted
    cfg = EnvConfig().updated({"action": {"type": "ContinuousAction", "acceleration_range": [-6, 3]}})
    assert cfg.action == "ContinuousAction" and cfg.acceleration_range == (-6.0, 3.0)


def test_lane_left_moves_toward_positive_n_and_truncation_at_duration():
    env = make(scenario="curve-single", perception="truth", duration=4.0)
    obs, info = env.reset(seed=0)
    assert info["lane"] == 0 and obs[0, COL["n"]] == pytest.approx(-1.75)
    assert env.get_available_actions() == [IDLE, 0, 3, 4]  # no LANE_RIGHT from the rightmost lane
    obs, *_ = env.step(0)  # LANE_LEFT
    steps, truncated = 1, False
    while not truncated:
        obs, reward, terminated, truncated, info = env.step(IDLE)
        steps += 1
        assert not terminated
    assert steps == 20 and info["t"] == pytest.approx(4.0)  # 4 s at 5 Hz
    assert info["lane"] == 1 and obs[0, COL["n"]] == pytest.approx(1.75, abs=0.25)


def test_reward_matches_highway_env_terms():
    env = make(scenario="curve-single", perception="truth", duration=1.0)
    env.reset(seed=0)
    _, reward, *_ , info = env.step(IDLE)  # lane 0 (rightmost) at 20 m/s: no speed reward yet
    r = info["rewards"]
    assert r["right_lane_reward"] == 1.0 and r["collision_reward"] == 0.0 and r["on_road_reward"] == 1.0
    expected = (0.4 * r["high_speed_reward"] + 0.1) / 1.5 + 1.0 / 1.5  # lmap from [-1, 0.5] onto [0, 1]
    assert reward == pytest.approx(expected)
    assert 0.0 <= r["high_speed_reward"] < 0.05


def test_continuous_action_brakes_the_ego():
    env = make(scenario="curve-single", perception="truth", action="ContinuousAction", duration=1.0)
    obs, _ = env.reset(seed=0)
    v0 = obs[0, COL["v"]]
    for _ in range(5):  # -1 -> -8 m/s^2 for 1 s
        obs, *_ = env.step(np.array([-1.0, 0.0], dtype=np.float32))
    assert obs[0, COL["v"]] == pytest.approx(v0 - 8.0, abs=0.05)


def test_rendered_frame_is_not_blank():
    env = TrackedRoadEnv({"scenario": "cut-in", "duration": 2.0, "screen_width": 320, "screen_height": 240},
                         render_mode="rgb_array")
    env.reset(seed=0)
    for _ in range(5):
        env.step(IDLE)
    frame = env.render()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    dark = np.all(frame < 60, axis=-1).sum()  # the ego, road edges, text
    green = ((frame[..., 1] > 100) & (frame[..., 0] < 100) & (frame[..., 2] < 100)).sum()  # lidar points
    assert dark > 100 and green > 5
    assert frame.std() > 10


def test_a_lane_map_whose_lanes_begin_and_end():
    """On freeway-us101 (simulated traffic on a lane map) ``info["lane_centers"]`` are the lanes at the ego's
    ``s``: NaN for the auxiliary lane before it begins; the planner drives it without a collision."""
    pytest.importorskip("commonroad")
    import math
    from pathlib import Path

    from sim.env.planner import planner_for

    path = Path(__file__).resolve().parents[1] / "scenarios" / "maps" / "freeway-us101.toml"
    env = TrackedRoadEnv({"scenario": str(path), "action": "ContinuousAction", "perception": "truth"})
    obs, info = env.reset(seed=0)
    road = env.world.road
    assert not road.uniform and len(info["lane_centers"]) == road.lanes == 6
    assert math.isnan(info["lane_centers"][0])  # the auxiliary lane begins further on
    expected = road.lane_centers_at(env.vehicle.frenet_s)
    np.testing.assert_allclose(info["lane_centers"][1:], expected[1:])
    planner = planner_for(env.settings, info["lane_centers"])
    seen = []
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(planner.act(obs, info["labels"], info["lane_centers"]))
        seen.append(info["lane_centers"][0])
        done = terminated or truncated
    assert not info["crashed"] and info["on_road"]
    np.testing.assert_allclose(info["lane_centers"], road.lane_centers_at(env.vehicle.frenet_s))  # NaN where absent
    assert env.vehicle.frenet_s > 40.0 and all(math.isnan(c) for c in seen)  # it drove; the lane begins at ~85 m


def test_a_replay_is_driven_from_its_planning_problem():
    """A replay scenario in the env: the ego is the recording's planning problem (``sim.world.driven``),
    the episode lasts to the end of the goal's time interval; a recorded ego named in the file is refused."""
    pytest.importorskip("commonroad")
    from sim.env.config import ConfigError
    from sim.world.replay import load_recording
    from sim.world.scenario import SCENARIO_DIR

    env = TrackedRoadEnv({"scenario": "real/real-lanker-1-1", "action": "ContinuousAction"})
    obs, info = env.reset(seed=0)
    p = load_recording(str(SCENARIO_DIR / "real" / "USA_Lanker-1_1_T-1.xml.gz"))[0].planning
    assert env.duration == pytest.approx(p.goal_time[1]) and env.max_episode_steps == 20
    ego = env.world.ego_state()
    assert (ego.x, ego.y, ego.v) == pytest.approx((p.x, p.y, p.v))
    steps = 0
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
        steps += 1
        done = terminated or truncated
    assert steps == 20 or info["crashed"]
    assert info["tracks"] > 0
    with pytest.raises(ConfigError, match="duration.*at most the scenario's duration \\(4 s\\)"):
        TrackedRoadEnv({"scenario": "real/real-lanker-1-1", "duration": 5.0})


def test_faults_key_overrides_the_scenarios_faults_and_is_validated():
    """``faults`` replaces the scenario's ``[faults]`` (fault-radar-missing's radar comes back with ``{}``);
    bad values, intervals beyond the episode and duplicated frames are one-line ``ConfigError``s."""
    env = TrackedRoadEnv({"scenario": "fault-radar-missing", "duration": 1.0})
    env.reset(seed=0)
    env.step(2)
    assert env.fault_injector is not None and env.fault_injector.counts["radar_detections_dropped"] > 0
    env = TrackedRoadEnv({"scenario": "fault-radar-missing", "duration": 1.0, "faults": {}})
    env.reset(seed=0)
    env.step(2)
    assert env.fault_injector is None and any(len(sf.frame.radar) for sf, _ in env.step_frames)
    with pytest.raises(ConfigError, match=r"config key 'faults': .*lidar_spikes"):
        TrackedRoadEnv({"faults": {"lidar_spikes": 2.0}})
    with pytest.raises(ConfigError, match=r"config key 'faults' = .*duplicate_frames is not supported in the loop"):
        TrackedRoadEnv({"faults": {"duplicate_frames": [1.0]}})
    with pytest.raises(ConfigError, match=r"config key 'faults': faults.lidar_dropout\[0\] = \[5.0, 30.0\]: must end by"):
        TrackedRoadEnv({"faults": {"lidar_dropout": [[5.0, 30.0]]}})


def test_a_variant_with_its_own_tracker_runs_in_the_env():
    """``stonesoup-gmphd`` steps Stone Soup's GM-PHD (its own factory), not ``tracker.Tracker``."""
    pytest.importorskip("stonesoup")
    from sim.baselines.stonesoup_gmphd import StoneSoupGMPHD

    env = TrackedRoadEnv({"scenario": "curve-single", "variant": "stonesoup-gmphd", "duration": 1.0})
    env.reset(seed=0)
    env.step(1)
    assert isinstance(env.tracker, StoneSoupGMPHD)
