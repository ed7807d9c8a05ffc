"""The soak's fault schedule: which faults hit which mission, when, for how long. Pure and seeded:
`make_schedule(seed, minutes)` is a function of its arguments only (its own random.Random), so a
failure found in a soak is re-flown by giving the same seed and minutes.

Time base. A fault's `at_s` counts from its mission's take-off command, not from the start of the
run: how long the ground phase of a mission takes (quad-control starting, SLAM finding the floor,
arming) varies from run to run, the airborne part is what faults are meant to hit. Missions are
laid out on a nominal timeline (NOMINAL_MISSION_S each) only to say how many faults `minutes`
of soak carry; the runner flies missions in order until its time is up.

Kinds and ranges (each range's reason is beside it in FAULT_RANGES):
  stream_stall          both stream sockets stop carrying data for 0.2-3 s, then deliver the backlog
  stream_degraded       both stream sockets get delay, jitter and loss stalls for a window
  control_loss          the control link (quad-control -> bridge) gets delay and loss stalls
  control_back_to_back  the bridge forwards each request with 1-2 others right behind it
  slam_server_kill      slam-server SIGKILLed, restarted after an outage (resumes its checkpoint)
  ground_station_kill   quad-control SIGKILLed: the firmware failsafe lands; ends the mission
  camera_blank          1-5 all-zero frames from the Kinect
  camera_malformed      1-3 frames with a band of garbage rows from the Kinect
  cpu_burners           1-2 CPU-burning processes beside the ground station for a window
  gusts                 the gust level changes for a window

Kinds are dealt from a shuffled deck holding each kind once, deck after deck, so any stretch of
len(FAULT_KINDS) * k faults holds every kind k times: FAULTS_PER_MINUTE * 60 = 150 faults in an
hour, each kind 15 times. At most one ground-station kill per mission, placed after the mission's
other faults have started (it ends the mission: later faults would never be injected).
"""

from __future__ import annotations

import math
import random
from dataclasses import asdict, dataclass, field

# The order is the report's.
FAULT_KINDS = (
    "stream_stall",
    "stream_degraded",
    "control_loss",
    "control_back_to_back",
    "slam_server_kill",
    "ground_station_kill",
    "camera_blank",
    "camera_malformed",
    "cpu_burners",
    "gusts",
)

# Per kind: parameter -> (low, high), drawn uniformly (integers where both bounds are ints).
# "duration_s" is how long the fault lasts (0 for one-off events).
FAULT_RANGES: dict[str, dict[str, tuple]] = {
    # 0.2 s: Linux's minimum TCP RTO, the shortest stall a lost segment causes; 3 s: well past
    # quad-control's 500 ms of IMU bridging (docs/control.md), so the tracking-lost path is hit.
    "stream_stall": {"duration_s": (0.2, 3.0)},
    # Around scenario 5's 20 +- 10 ms, 2 % loss stalls: 5-40 ms one way (a quiet to a busy 2.4 GHz
    # channel), up to 20 ms jitter, 0.5-3 % of chunks held one 200 ms RTO; 3-15 s windows.
    "stream_degraded": {
        "duration_s": (3.0, 15.0),
        "delay_ms": (5.0, 40.0),
        "jitter_ms": (0.0, 20.0),
        "loss": (0.005, 0.03),
    },
    # The control link's scenario 5 (test_scenario_live.py): 2 % loss stalls; 1-4 % here. Two
    # stalls in a row (400 ms) pass the firmware's 250 ms failsafe, so a failsafe landing is an
    # expected outcome of this fault (outcome rules in soak.runner).
    "control_loss": {
        "duration_s": (2.0, 10.0),
        "delay_ms": (2.0, 20.0),
        "loss": (0.01, 0.04),
    },
    # 1-2 extra lines: bursts of 2-3 requests, what the firmware guarantees to keep.
    "control_back_to_back": {"duration_s": (3.0, 15.0), "extra_lines": (1, 2)},
    # The outage before a supervisor restarts it: 0.5-3 s (the scenario's 1 s in the middle).
    "slam_server_kill": {"duration_s": (0.5, 3.0)},
    "ground_station_kill": {"duration_s": (0.0, 0.0)},
    # Scenario 6's run of 3, and 1-5 in general (a Kinect glitch rarely lasts longer).
    "camera_blank": {"duration_s": (0.0, 0.0), "frames": (1, 5)},
    "camera_malformed": {"duration_s": (0.0, 0.0), "frames": (1, 3)},
    # The load scenario's 2 workers (one per core of the 2-core machine) and half of it; 5-20 s.
    "cpu_burners": {"duration_s": (5.0, 20.0), "workers": (1, 2)},
    # 0.05-0.3 m/s^2 (quad_model.QuadParams: 0.3 is a draughty indoor space; the scenarios fly
    # 0.15) for 5-20 s, then back to the run's base level.
    "gusts": {"duration_s": (5.0, 20.0), "gust_accel_std_mss": (0.05, 0.3)},
}

# No fault in the first 8 s after the take-off command: the climb to the 1.7 m hold takes ~5-8 s,
# during which the camera is within the Kinect's 0.5 m minimum range of the floor for the first
# ~0.3 m and SLAM builds its first keyframes and the floor plane; a fault there tests the map's
# start, which every mission's start already covers, and no scenario flies faults before the hover.
TAKEOFF_QUIET_S = 8.0
# Faults start before this many seconds after the take-off command: a mission that is not cut short
# is airborne ~95 s (hold, four waypoints, two turns; measured in short soaks), and a fault must
# start while there is flight left to judge it by.
FAULT_WINDOW_END_S = 75.0
# A nominal mission, ground phase included (quad-control start, tracking, arming ~25 s; airborne
# ~95 s; landing ~10 s): lays missions on the timeline that `minutes` counts in.
NOMINAL_MISSION_S = 130.0
# 2.5 faults a minute: 150 an hour, every kind 15 times (>= 10 with margin), ~5 per mission, so
# faults overlap in most missions.
FAULTS_PER_MINUTE = 2.5
# Share of faults placed to start inside the previous fault's window, so that overlaps happen by
# design and not only by chance.
FORCED_OVERLAP_SHARE = 0.3
# The schedule holds missions for this many times `minutes`: missions cut short by a ground-station
# kill take less time than nominal, and the runner must not run out of planned missions.
SPARE_FACTOR = 2.0
# Turns in place per mission (the scenario 8 manoeuvre): one each way, in a seeded order.
TURN_DEG = 90.0
DEFAULT_SEED = 20261206


@dataclass(frozen=True)
class Fault:
    kind: str
    mission: int  # 1-based
    at_s: float  # after the mission's take-off command
    duration_s: float
    params: dict = field(default_factory=dict)

    @property
    def end_s(self) -> float:
        return self.at_s + self.duration_s

    @property
    def fault_id(self) -> str:
        return f"m{self.mission:03d}-{self.kind}@{self.at_s:.1f}s"


@dataclass(frozen=True)
class MissionPlan:
    index: int  # 1-based
    nominal_start_s: float  # on the nominal timeline
    faults: tuple  # Faults sorted by at_s
    turns_ccw_deg: tuple


@dataclass(frozen=True)
class Schedule:
    seed: int
    minutes: float
    missions: tuple

    def faults(self, within_minutes: float | None = None) -> list[Fault]:
        """Every fault, or those of missions that start within `within_minutes` nominally."""
        limit = None if within_minutes is None else within_minutes * 60.0
        return [
            f for m in self.missions if limit is None or m.nominal_start_s < limit for f in m.faults
        ]

    def to_dict(self) -> dict:
        return {
            "seed": self.seed,
            "minutes": self.minutes,
            "missions": [
                {
                    **{k: v for k, v in asdict(m).items() if k != "faults"},
                    "faults": [asdict(f) for f in m.faults],
                }
                for m in self.missions
            ],
        }


def overlapping_pairs(faults: list[Fault]) -> list[tuple[Fault, Fault]]:
    """Pairs of faults of one mission whose windows overlap (a one-off event overlaps a window it
    falls into)."""
    out = []
    by_mission: dict[int, list[Fault]] = {}
    for f in faults:
        by_mission.setdefault(f.mission, []).append(f)
    for group in by_mission.values():
        group = sorted(group, key=lambda f: f.at_s)
        for i, a in enumerate(group):
            for b in group[i + 1 :]:
                if b.at_s <= a.end_s:
                    out.append((a, b))
    return out


def _draw(rng: random.Random, low, high):
    if isinstance(low, int) and isinstance(high, int):
        return rng.randint(low, high)
    return round(rng.uniform(low, high), 3)


def make_schedule(seed: int = DEFAULT_SEED, minutes: float = 60.0) -> Schedule:
    """The missions and faults of a soak of `minutes` (plus spare missions), from `seed`."""
    if not (isinstance(minutes, (int, float)) and math.isfinite(minutes) and minutes > 0):
        raise ValueError(f"minutes must be a positive number, not {minutes!r}")
    rng = random.Random(seed)
    n_missions = max(1, math.ceil(minutes * 60.0 * SPARE_FACTOR / NOMINAL_MISSION_S))
    per_mission = FAULTS_PER_MINUTE * NOMINAL_MISSION_S / 60.0
    n_faults = math.ceil(n_missions * per_mission)
    kinds: list[str] = []
    while len(kinds) < n_faults:
        deck = list(FAULT_KINDS)
        rng.shuffle(deck)
        kinds.extend(deck)
    kinds = kinds[:n_faults]
    # Deal faults to missions evenly in order (fault j to mission floor(j / per_mission)), then
    # move a second ground-station kill of a mission to the next mission without one (swapping
    # kinds with one of its faults), so the deck's counts are kept.
    groups: list[list[str]] = [[] for _ in range(n_missions)]
    for j, kind in enumerate(kinds):
        groups[min(n_missions - 1, int(j / per_mission))].append(kind)
    for i, group in enumerate(groups):
        while group.count("ground_station_kill") > 1:
            moved = False
            for later in groups[i + 1 :]:
                if "ground_station_kill" not in later and later:
                    k = next(n for n, kd in enumerate(later) if kd != "ground_station_kill")
                    later[k], group[group.index("ground_station_kill")] = (
                        "ground_station_kill",
                        later[k],
                    )
                    moved = True
                    break
            if not moved:
                group.remove("ground_station_kill")  # the schedule's last mission: dropped
    missions = []
    for i, group in enumerate(groups):
        index = i + 1
        faults: list[Fault] = []
        rng.shuffle(group)
        for kind in group:
            if kind == "ground_station_kill":
                continue
            params = {k: _draw(rng, lo, hi) for k, (lo, hi) in FAULT_RANGES[kind].items()}
            duration = float(params.pop("duration_s"))
            latest = max(TAKEOFF_QUIET_S, FAULT_WINDOW_END_S - duration)
            if faults and rng.random() < FORCED_OVERLAP_SHARE:
                prev = faults[-1]
                at = rng.uniform(prev.at_s, max(prev.at_s, min(prev.end_s, latest)))
            else:
                at = rng.uniform(TAKEOFF_QUIET_S, latest)
            faults.append(Fault(kind, index, round(at, 3), round(duration, 3), params))
        if "ground_station_kill" in group:
            first_starts = [f.at_s for f in faults]
            earliest = max(first_starts, default=TAKEOFF_QUIET_S)
            at = rng.uniform(min(earliest + 1.0, FAULT_WINDOW_END_S), FAULT_WINDOW_END_S)
            faults.append(Fault("ground_station_kill", index, round(at, 3), 0.0, {}))
        turns = (TURN_DEG, -TURN_DEG) if rng.random() < 0.5 else (-TURN_DEG, TURN_DEG)
        missions.append(
            MissionPlan(
                index,
                round(i * NOMINAL_MISSION_S, 1),
                tuple(sorted(faults, key=lambda f: f.at_s)),
                turns,
            )
        )
    return Schedule(seed, float(minutes), tuple(missions))
