"""The arm's failure predicates on `ArmState`s built here (no simulation): each fires where it should and only
there, their parameters are validated, a predicate of the wrong kind of robot is refused, and "same failure"
for arm signatures (the tolerance scaled to a table, the touched models)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import pytest

from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.oracle import (
    ARM_DEFAULTS,
    BUILT_IN,
    GROUND,
    PREDICATES,
    ArmState,
    Contact,
    FailureSignature,
    History,
    PredicateSpec,
    SameFailureRule,
    check_predicate_models,
    check_predicates_for_robot,
    default_predicates,
    make_predicate,
    predicate,
    predicate_spec,
    robots_of,
    same_failure,
    why_other,
)
from pytest_ddenv.oracle.arm_state import GRIPPER_CLOSE, GRIPPER_OPEN, Pose6
from pytest_ddenv.oracle.predicates import Predicate, RobotState

TABLE_TOP = 0.40
MUG_START: Pose6 = (0.5, 0.0, 0.45, 0.0, 0.0, 0.0)
VASE_START: Pose6 = (0.6, 0.2, 0.50, 0.0, 0.0, 0.0)
BOX_START: Pose6 = (0.4, -0.2, 0.45, 0.0, 0.0, 0.0)
PLACE = (0.3, 0.4, None)
JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
LOWER = (-2.9, -1.76, -2.9, -3.07, -2.9, -0.02, -2.9)
UPPER = (2.9, 1.76, 2.9, -0.07, 2.9, 3.75, 2.9)
HOME = (0.0, -0.78, 0.0, -2.36, 0.0, 1.57, 0.78)


def finger(model: str, link: str = "panda_leftfinger", force: float = 10.0) -> Contact:
    return Contact(model, link, False, force, finger=True)


def link(model: str, name: str = "panda_hand", force: float = 10.0) -> Contact:
    return Contact(model, name, False, force)


def both_fingers(model: str = "mug") -> tuple[Contact, ...]:
    return finger(model, "panda_leftfinger"), finger(model, "panda_rightfinger")


def arm_state(time: float = 1.0, *, history: History | None = None, mug: Pose6 = MUG_START,
              objects: Mapping[str, Pose6] | None = None, **fields: Any) -> ArmState:
    """An arm state at `time`: a Panda at home over a table with a mug (the target), a vase and a box."""
    values: dict[str, Any] = {
        "time": time, "timeout": 20.0, "pose": (0.5, 0.0, 0.6, math.pi, 0.0, 0.0),
        "history": history if history is not None else History(),
        "joint_names": JOINTS, "joint_positions": HOME, "joint_velocities": (0.0,) * 7,
        "joint_lower": LOWER, "joint_upper": UPPER,
        "gripper_opening": 0.08, "gripper_command": GRIPPER_OPEN, "gripper_since": 0.0,
        "contacts": (), "self_contacts": (), "target": "mug", "target_held": False,
        "objects": dict(objects) if objects is not None else {
            "mug": mug, "table": (0.5, 0.0, 0.2, 0.0, 0.0, 0.0), "vase": VASE_START, "box": BOX_START},
        "start_objects": {"mug": MUG_START, "table": (0.5, 0.0, 0.2, 0.0, 0.0, 0.0), "vase": VASE_START,
                          "box": BOX_START},
        "place": PLACE, "place_tolerance": 0.05, "table": "table", "table_top": TABLE_TOP,
    }
    values.update(fields)
    values["history"].append(time, values["pose"][:3])
    return ArmState(**values)


def first_failure(predicate_: Predicate, states: Iterable[ArmState]) -> tuple[int, FailureSignature] | None:
    """The tick index and signature of the first failure over `states` (after a reset), None if none."""
    predicate_.reset()
    for index, state in enumerate(states):
        found = predicate_.check(state)
        if found is not None:
            return index, found
    return None


def ticks(start: float, stop: float, step: float = 0.05) -> list[float]:
    return [round(start + i * step, 6) for i in range(round((stop - start) / step) + 1)]


# -- arm_collision ------------------------------------------------------------------------------------
def test_arm_collision_fires_on_a_model_other_than_the_target_and_the_table() -> None:
    collision = make_predicate("arm_collision")
    assert collision.check(arm_state(contacts=(*both_fingers(), link("table", "panda_link0", 200.0)))) is None
    hit = collision.check(arm_state(contacts=(finger("mug"), link("tall_box", "panda_hand", 35.0))))
    assert hit is not None and hit.predicate == "arm_collision"
    assert hit.detail == "Link panda_hand hit 'tall_box' (35 N)."
    assert hit.touched == ("tall_box",)  # the target is not a culprit
    assert hit.pose == (0.5, 0.0, 0.6, math.pi, 0.0, 0.0)


def test_arm_collision_counts_the_ground_and_the_fingers_and_ignores_light_touches() -> None:
    collision = make_predicate("arm_collision", min_force=5.0)
    assert collision.check(arm_state(contacts=(finger("vase", force=4.9),))) is None
    fingers = collision.check(arm_state(contacts=(finger("vase", force=5.0),)))
    assert fingers is not None and fingers.detail == "Link panda_leftfinger hit 'vase' (5 N)."
    ground = collision.check(arm_state(contacts=(link(GROUND, "panda_link3"),)))
    assert ground is not None and ground.detail.startswith("Link panda_link3 hit the ground")
    assert ground.touched == ()


def test_arm_collision_with_models_watches_only_those() -> None:
    collision = make_predicate("arm_collision", models=["vase"])
    assert collision.check(arm_state(contacts=(link("box"), link(GROUND)))) is None
    assert collision.check(arm_state(contacts=(link("vase"),))) is not None


# -- grasp_failed --------------------------------------------------------------------------------------
def grasp(times: Iterable[float], *, closed_at: float, held: bool, opening: float = 0.04,
          contacts: tuple[Contact, ...] = ()) -> list[ArmState]:
    history = History()
    return [arm_state(t, history=history, gripper_command=GRIPPER_CLOSE if t >= closed_at else GRIPPER_OPEN,
                      gripper_since=closed_at if t >= closed_at else 0.0, target_held=held and t >= closed_at,
                      gripper_opening=opening, contacts=contacts) for t in times]


def test_grasp_failed_fires_once_settle_seconds_after_a_close_without_the_target() -> None:
    states = grasp(ticks(0.0, 4.0), closed_at=2.0, held=False, contacts=(finger("mug"), finger("box",
                   "panda_rightfinger")))
    found = first_failure(make_predicate("grasp_failed", settle=0.6), states)
    assert found is not None
    index, failure = found
    assert states[index].time == pytest.approx(2.6)
    assert failure.detail == ("Only finger panda_leftfinger touches the target 'mug' 0.6 s after closing "
                              "(fingers 0.040 m apart, the fingers touch 'box').")
    assert failure.touched == ("box",)


def test_grasp_failed_fires_when_the_fingers_close_on_nothing() -> None:
    states = grasp(ticks(0.0, 3.0), closed_at=1.0, held=False, opening=0.002)
    found = first_failure(make_predicate("grasp_failed"), states)
    assert found is not None
    assert found[1].detail == "The fingers closed to 0.002 m without the target 'mug'."


def test_grasp_failed_never_fires_before_a_close_nor_on_a_held_target_nor_twice() -> None:
    assert first_failure(make_predicate("grasp_failed"), grasp(ticks(0.0, 5.0), closed_at=9.0, held=False)) is None
    held = grasp(ticks(0.0, 5.0), closed_at=1.0, held=True, contacts=both_fingers())
    assert first_failure(make_predicate("grasp_failed"), held) is None
    # a grasp that held and later loses the target is object_dropped's, not grasp_failed's
    later = [replace(state, target_held=False) if state.time > 3.0 else state for state in held]
    assert first_failure(make_predicate("grasp_failed"), later) is None
    failing = make_predicate("grasp_failed")
    fired = [s for s in grasp(ticks(0.0, 5.0), closed_at=1.0, held=False) if failing.check(s) is not None]
    assert len(fired) == 1


def test_grasp_failed_judges_each_close_and_resets_between_runs() -> None:
    first = grasp(ticks(0.0, 2.0), closed_at=0.5, held=True, contacts=both_fingers())
    second = grasp(ticks(2.05, 4.0), closed_at=3.0, held=False)
    grasp_failed = make_predicate("grasp_failed")
    found = first_failure(grasp_failed, [*first, *second])
    assert found is not None and found[1].time == pytest.approx(3.6)
    assert first_failure(grasp_failed, first) is None  # reset: nothing left of the run before


# -- object_dropped ------------------------------------------------------------------------------------
def carry(drop_at: float | None, *, open_at: float | None = None, lift: float = 0.2) -> list[ArmState]:
    """Closed at 1 s, lifted from 1.5 s, the mug leaves the gripper at `drop_at`, the gripper opens at `open_at`."""
    history, states = History(), []
    for t in ticks(0.0, 5.0):
        height = lift * min(1.0, max(0.0, (t - 1.5) / 0.5))
        dropped = drop_at is not None and t >= drop_at
        opened = open_at is not None and t >= open_at
        mug = (0.5, 0.0, TABLE_TOP + 0.05 if dropped else MUG_START[2] + height, 0.0, 0.0, 0.0)
        states.append(arm_state(t, history=history, mug=mug,
                                gripper_command=GRIPPER_OPEN if t < 1.0 or opened else GRIPPER_CLOSE,
                                gripper_since=open_at if opened else 1.0 if t >= 1.0 else 0.0,
                                target_held=1.0 <= t and not dropped and not opened,
                                contacts=both_fingers() if 1.0 <= t and not dropped and not opened else ()))
    return states


def test_object_dropped_fires_when_the_lifted_target_leaves_the_closed_gripper() -> None:
    states = carry(drop_at=3.0)
    found = first_failure(make_predicate("object_dropped", duration=0.2), states)
    assert found is not None
    index, failure = found
    assert states[index].time == pytest.approx(3.15)  # last held at 2.95 s
    assert failure.detail == ("'mug' left the gripper 0.25 m above the table (not held for 0.20 s, gripper still "
                              "closed).")


def test_object_dropped_does_not_fire_on_a_place_a_target_never_lifted_or_a_short_slip() -> None:
    assert first_failure(make_predicate("object_dropped"), carry(drop_at=None)) is None
    assert first_failure(make_predicate("object_dropped"), carry(drop_at=3.0, open_at=3.0)) is None  # placed
    assert first_failure(make_predicate("object_dropped"), carry(drop_at=1.2)) is None  # not lifted yet
    slip = [replace(s, target_held=False) if 3.0 <= s.time < 3.1 else s for s in carry(drop_at=None)]
    assert first_failure(make_predicate("object_dropped", duration=0.2), slip) is None


# -- not_placed and timeout ----------------------------------------------------------------------------
PLACED: Pose6 = (0.31, 0.41, 0.45, 0.0, 0.0, 0.3)


@pytest.mark.parametrize(("mug", "held", "detail"), [
    ((0.5, 0.0, 0.45, 0.0, 0.0, 0.0), False, "'mug' is 0.45 m from the centre of the place region (tolerance 0.05 m)"),
    ((0.31, 0.41, 0.60, 0.0, 0.0, 0.0), True, "'mug' is in the place region but still in the gripper"),
    ((0.31, 0.41, 0.42, 1.57, 0.0, 0.0), False,
     "'mug' is in the place region but not resting on the table (-0.03 m from its resting height)"),
])
def test_not_placed_fires_at_the_time_limit_when_the_target_is_not_placed(mug: Pose6, held: bool,
                                                                         detail: str) -> None:
    not_placed = make_predicate("not_placed")
    assert not_placed.check(arm_state(19.9, mug=mug, target_held=held)) is None
    failure = not_placed.check(arm_state(20.0, mug=mug, target_held=held))
    assert failure is not None and failure.detail == f"At t = 20.00 s {detail}."
    assert not_placed.check(arm_state(20.05, mug=mug, target_held=held)) is None  # once


def test_not_placed_passes_a_placed_target_and_takes_at_and_its_own_tolerance() -> None:
    assert make_predicate("not_placed").check(arm_state(20.0, mug=PLACED)) is None
    early = make_predicate("not_placed", at=5.0)
    assert early.check(arm_state(4.95)) is None
    assert early.check(arm_state(5.0)) is not None
    loose = make_predicate("not_placed", place_tolerance=0.5)
    assert loose.check(arm_state(20.0)) is None


def test_not_placed_without_a_target_is_a_clear_error() -> None:
    with pytest.raises(ScenarioError, match="names no target"):
        make_predicate("not_placed").check(arm_state(20.0, target=None))


def test_timeout_on_an_arm_fires_at_the_limit_when_the_target_is_not_placed() -> None:
    timeout = make_predicate("timeout")
    assert timeout.check(arm_state(19.0)) is None
    failure = timeout.check(arm_state(20.0))
    assert failure is not None and failure.predicate == "timeout"
    assert failure.detail == ("The target is not placed after 20 s: 'mug' is 0.45 m from the centre of the place "
                              "region (tolerance 0.05 m).")
    assert timeout.check(arm_state(20.0, mug=PLACED)) is None
    no_target = timeout.check(arm_state(20.0, target=None))
    assert no_target is not None and no_target.detail == "The time limit of 20 s was reached."


def test_timeout_on_a_mobile_robot_is_unchanged() -> None:
    history = History()
    history.append(8.0, (1.0, 0.0, 0.1))
    state = RobotState(8.0, 8.0, (1.0, 0.0, 0.1, 0.0, 0.0, 0.0), (0.0,) * 6, (0.0,) * 6, (4.0, 0.0, None), 3.0,
                       (), (0.0,) * 4, 400.0, history)
    failure = make_predicate("timeout").check(state)
    assert failure is not None and failure.detail == "Goal still 3.00 m away after 8 s."


# -- knocked_over --------------------------------------------------------------------------------------
def with_object(name: str, pose: Pose6) -> dict[str, Pose6]:
    return {"mug": MUG_START, "table": (0.5, 0.0, 0.2, 0.0, 0.0, 0.0), "vase": VASE_START, "box": BOX_START,
            name: pose}


def test_knocked_over_fires_on_a_tipped_or_fallen_watched_object() -> None:
    knocked = make_predicate("knocked_over")
    assert knocked.check(arm_state(objects=with_object("vase", (0.62, 0.2, 0.5, 0.2, 0.1, 2.0)))) is None
    tipped = knocked.check(arm_state(objects=with_object("vase", (0.7, 0.2, 0.45, 1.5, 0.0, 0.0))))
    assert tipped is not None and tipped.detail == "'vase' was knocked over (tilted 86 deg, limit 45 deg)."
    assert tipped.touched == ("vase",)
    fallen = knocked.check(arm_state(objects=with_object("box", (0.9, -0.2, 0.05, 0.0, 0.0, 0.0))))
    assert fallen is not None and fallen.detail == "'box' fell off the table (0.35 m below the table top)."


def test_knocked_over_compares_with_the_start_orientation_and_watches_only_named_models() -> None:
    lying = (0.6, 0.2, 0.45, math.pi / 2, 0.0, 0.0)
    state = arm_state(objects=with_object("vase", lying), start_objects=with_object("vase", lying))
    assert make_predicate("knocked_over").check(state) is None  # it lay on its side from the start
    tipped = arm_state(objects=with_object("vase", (0.7, 0.2, 0.45, 1.5, 0.0, 0.0)))
    assert make_predicate("knocked_over", models=["box"]).check(tipped) is None
    # the target is the arm's to move; a model a reduction removed is not there to tip
    assert make_predicate("knocked_over").check(arm_state(mug=(0.5, 0.0, 0.45, 1.5, 0.0, 0.0))) is None
    assert make_predicate("knocked_over", models=["gone"]).check(arm_state()) is None


# -- joint_limit and self_collision ---------------------------------------------------------------------
def test_joint_limit_fires_after_duration_seconds_near_a_limit() -> None:
    near = (*HOME[:3], -0.08, *HOME[4:])  # joint 4: 0.01 rad from its upper limit -0.07
    history = History()
    states = [arm_state(t, history=history, joint_positions=near if t >= 1.0 else HOME) for t in ticks(0.0, 3.0)]
    found = first_failure(make_predicate("joint_limit", margin=0.02, duration=0.5), states)
    assert found is not None and states[found[0]].time == pytest.approx(1.5)
    assert found[1].detail == "Joint panda_joint4 at -0.080, 0.010 from its upper limit -0.070 for 0.50 s."
    brief = [replace(s, joint_positions=HOME) if s.time >= 1.4 else s for s in states]
    assert first_failure(make_predicate("joint_limit", duration=0.5), brief) is None


def test_joint_limit_skips_joints_without_finite_limits() -> None:
    lower = (-math.inf, *LOWER[1:])
    state = arm_state(joint_positions=(-50.0, *HOME[1:]), joint_lower=lower)
    assert first_failure(make_predicate("joint_limit", duration=0.0), [state]) is None


def test_self_collision_fires_on_any_self_contact() -> None:
    assert make_predicate("self_collision").check(arm_state()) is None
    failure = make_predicate("self_collision").check(arm_state(self_contacts=(("panda_link2", "panda_hand"),)))
    assert failure is not None and failure.detail == "The arm touches itself: links panda_link2 and panda_hand."


# -- registration, parameters, kinds -------------------------------------------------------------------
def test_every_arm_predicate_is_built_in_and_for_arms() -> None:
    names = {"arm_collision", "grasp_failed", "object_dropped", "not_placed", "knocked_over", "joint_limit",
             "self_collision"}
    assert names <= BUILT_IN and names <= set(PREDICATES)
    assert {robots_of(PREDICATES[name]) for name in names} == {"arm"}
    assert {robots_of(PREDICATES[name]) for name in ("stuck", "flipped", "high_centered", "fell", "collided")} == {
        "mobile"}
    assert robots_of(PREDICATES["timeout"]) == "any"
    assert set(ARM_DEFAULTS) <= names


def test_the_default_predicates_are_the_arms_for_an_arm_and_none_for_a_mobile_robot() -> None:
    specs = default_predicates("arm")
    assert [spec.name for spec in specs] == list(ARM_DEFAULTS)
    assert [spec.build().name for spec in specs] == list(ARM_DEFAULTS)
    check_predicates_for_robot(specs, "arm", "panda")
    assert default_predicates("mobile") == ()
    with pytest.raises(ValueError, match="kind must be"):
        default_predicates("boat")


@pytest.mark.parametrize(("name", "params", "message"), [
    ("grasp_failed", {"settle": -1}, "grasp_failed.settle.*a number >= 0"),
    ("grasp_failed", {"min_opening": "small"}, "grasp_failed.min_opening.*a finite number"),
    ("object_dropped", {"min_lift": math.nan}, "object_dropped.min_lift.*a finite number"),
    ("not_placed", {"place_tolerance": 0}, "not_placed.place_tolerance.*a number > 0"),
    ("not_placed", {"at": -2.0}, "not_placed.at.*a number >= 0"),
    ("knocked_over", {"max_tilt": 0}, "knocked_over.max_tilt.*a number > 0"),
    ("knocked_over", {"models": "vase"}, "knocked_over.models.*a list of model names"),
    ("arm_collision", {"models": []}, "arm_collision.models.*at least one model name"),
    ("joint_limit", {"margin": -0.1}, "joint_limit.margin.*a number >= 0"),
    ("self_collision", {"duration": 1.0}, "predicate 'self_collision' has no parameter 'duration'"),
])
def test_arm_predicate_parameters_are_checked_with_a_clear_error(name: str, params: dict[str, Any],
                                                                 message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        make_predicate(name, **params)


def test_an_arm_predicate_naming_a_model_the_world_lacks_is_refused() -> None:
    specs = (predicate_spec("knocked_over", {"models": ["vase", "vsae"]}),)
    with pytest.raises(ScenarioError, match=r"'knocked_over' predicate names 'vsae', which is not a model of t\.yaml"):
        check_predicate_models(specs, ["mug", "vase", "table"], "t.yaml")
    check_predicate_models((predicate_spec("arm_collision"),), ["mug"], "t.yaml")


def test_a_predicate_for_the_other_kind_of_robot_is_refused_with_the_valid_ones() -> None:
    with pytest.raises(ScenarioError) as refused:
        check_predicates_for_robot([make_predicate("timeout"), make_predicate("stuck")], "arm", "panda")
    assert str(refused.value).startswith(
        "predicate 'stuck' is for mobile robots; the world's robot 'panda' is an arm; arm predicates: "
        "arm_collision, grasp_failed, joint_limit, knocked_over, not_placed, object_dropped, self_collision, "
        "timeout")
    with pytest.raises(ScenarioError, match="predicate 'grasp_failed' is for arms; the world's robot 'husky' is a "
                                            "mobile robot; mobile predicates: collided, fell, flipped"):
        check_predicates_for_robot([PredicateSpec("grasp_failed")], "mobile", "husky")


def test_predicates_of_a_user_are_for_any_robot_unless_they_say_so() -> None:
    @predicate
    def always(state: Any) -> bool:
        return True

    check_predicates_for_robot([always, predicate_spec(always)], "arm", "panda")
    check_predicates_for_robot([always], "mobile", "husky")

    def never(state: Any) -> bool:
        return False

    lifted = predicate(never, name="lifted", robots="arm")
    check_predicates_for_robot([lifted], "arm", "panda")
    with pytest.raises(ScenarioError, match="predicate 'lifted' is for arms"):
        check_predicates_for_robot([predicate_spec(lifted)], "mobile", "husky")
    with pytest.raises(ScenarioError, match=r"predicate 'lifted': robots.*one of mobile, arm, any"):
        predicate(never, name="lifted", robots="arms")


@dataclass
class Grazed:
    """A predicate object of a user's, for arms only."""

    robots = "arm"
    name: str = "grazed"

    def reset(self) -> None:
        pass

    def check(self, state: ArmState) -> FailureSignature | None:
        return None


def test_a_users_predicate_object_says_its_robots_by_an_attribute() -> None:
    check_predicates_for_robot([Grazed()], "arm", "panda")
    with pytest.raises(ScenarioError, match="predicate 'grazed' is for arms; the world's robot 'husky'"):
        check_predicates_for_robot([Grazed()], "mobile", "husky")
    wrong = Grazed()
    wrong.robots = "arms"
    with pytest.raises(ScenarioError, match=r"robots attribute of predicate 'grazed'.*one of mobile, arm, any"):
        check_predicates_for_robot([wrong], "arm", "panda")


# -- "same failure" for arms -----------------------------------------------------------------------------
def grasp_signature(x: float, *touched: str) -> FailureSignature:
    return FailureSignature("grasp_failed", 2.6, (x, 0.0, 0.5, math.pi, 0.0, 0.0), touched)


def test_an_arm_failure_is_at_the_same_place_within_0_15_m_by_default() -> None:
    reference = grasp_signature(0.50, "box")
    assert same_failure(grasp_signature(0.58, "box"), reference)
    assert not same_failure(grasp_signature(0.70, "box"), reference)  # 0.2 m: another place on a table
    assert SameFailureRule().same(grasp_signature(0.58, "box"), reference)
    assert not SameFailureRule().same(grasp_signature(0.70, "box"), reference)
    reason = why_other(grasp_signature(0.70, "box"), reference)
    assert reason is not None
    assert reason.text == "the same predicate fired 0.20 m from the reference failure (more than 0.15 m)"
    assert SameFailureRule().describe(reference).startswith("grasp_failed within 0.15 m, touching one of")
    # a tolerance the user chose applies as given; mobile failures keep the default 0.5 m
    assert SameFailureRule(tolerance=0.3).same(grasp_signature(0.70, "box"), reference)
    stuck = FailureSignature("stuck", 9.0, (1.0, 0.0, 0.2, 0.0, 0.0, 0.0), ("wall",))
    assert same_failure(replace(stuck, pose=(1.4, 0.0, 0.2, 0.0, 0.0, 0.0)), stuck)
    timeout = FailureSignature("timeout", 20.0, (0.5, 0.0, 0.5, 0.0, 0.0, 0.0))  # any robot's: as given
    assert same_failure(replace(timeout, pose=(0.9, 0.0, 0.5, 0.0, 0.0, 0.0)), timeout)


def test_grasp_failures_touching_different_neighbours_follow_the_users_rule() -> None:
    reference = grasp_signature(0.50, "box")
    other_neighbour = grasp_signature(0.52, "vase")
    assert not SameFailureRule().same(other_neighbour, reference)  # "all": one of the reference's models
    assert SameFailureRule("place").same(other_neighbour, reference)
    assert not SameFailureRule("touched").same(other_neighbour, reference)
    assert SameFailureRule("touched").same(grasp_signature(0.9, "box", "vase"), reference)
    reason = why_other(other_neighbour, reference)
    assert reason is not None and reason.advice == "consider same_failure='place'"


def test_an_arm_signature_leaves_the_target_and_the_table_out_of_what_was_touched() -> None:
    state = arm_state(contacts=(*both_fingers(), link("table", "panda_link0"), link("box", force=0.5)))
    failure = make_predicate("grasp_failed", settle=0.0).check(replace(state, gripper_command=GRIPPER_CLOSE,
                                                                       gripper_opening=0.001))
    assert failure is not None and failure.touched == ("box",)
    assert failure.explain() == (
        "The 'grasp_failed' predicate fired at t = 1.00 s with the end effector at (0.50, 0.00, 0.60) m, roll 180 "
        "deg, pitch 0 deg, yaw 0 deg, touching box besides the target and the table. The fingers closed to 0.001 m "
        "without the target 'mug'.")
    alone = make_predicate("self_collision").check(arm_state(self_contacts=(("panda_link1", "panda_link5"),)))
    assert alone is not None and "touching no model besides the target and the table." in alone.explain()
