"""Property-based tests (hypothesis): any value for any numeric config field or option is either a valid
config or one IrlsimError line, never another exception; collection's episode seeds stay in SUMO's range;
the road's (s, d) -> xy -> (s, d) round trip is exact; an aggregate's identity is its members'
identities in order whatever their paths, with every member's seeds; any action or theta the Gymnasium
environment gets is a valid one or one line."""

import argparse
import dataclasses
import math
import typing

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from irlsim.config import MAX_SEED, float_in, int_in, load_config
from irlsim.data.collection import SEED_STRIDE, SPLITS, CollectConfig
from irlsim.errors import IrlsimError
from irlsim.train.config import Stage1Config, Stage2Config


def _numeric_fields(cls, prefix=""):
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp = hints[f.name]
        if dataclasses.is_dataclass(tp):
            yield from _numeric_fields(tp, f"{prefix}{f.name}.")
        elif tp in (int, float):
            yield f"{prefix}{f.name}"


VALUES = st.one_of(
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -1, 1, 2**31, 2**31 - 1, 10**7, 1e-12, -0.0]),
)


@pytest.mark.parametrize("cls", [Stage1Config, Stage2Config, CollectConfig])
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_any_numeric_override_is_a_valid_config_or_one_line(cls, data):
    keys = sorted(_numeric_fields(cls))
    chosen = data.draw(st.lists(st.sampled_from(keys), min_size=1, max_size=3, unique=True))
    overrides = {k: data.draw(VALUES) for k in chosen}
    try:
        cfg = load_config(cls, None, overrides)
    except IrlsimError as e:
        assert str(e) and "\n" not in str(e)
        return
    for k, v in overrides.items():  # accepted: finite, and what was asked
        got = cfg
        for part in k.split("."):
            got = getattr(got, part)
        assert math.isfinite(got) and got == (float(v) if isinstance(got, float) else v)


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(min_value=0, max_value=10_000),
    n=st.tuples(*(st.integers(min_value=0, max_value=99_999) for _ in SPLITS)),
)
def test_accepted_collection_seeds_derive_episode_seeds_in_sumos_range(seed, n):
    counts = {f"{s}_episodes": max(k, 1 if s == "train" else 0) for s, k in zip(SPLITS, n, strict=True)}
    try:
        cfg = load_config(CollectConfig, None, {"seed": seed, **counts})
    except IrlsimError as e:
        assert "seed must be in 0.." in str(e)
        # refused only when the largest episode seed would pass SUMO's limit
        assert (
            seed * SEED_STRIDE + 200_000 + 99_999 > MAX_SEED
            or seed * SEED_STRIDE
            + max(off + c - 1 for off, c in zip((0, 100_000, 200_000), counts.values(), strict=True))
            > MAX_SEED
        )
        return
    seeds = [s for split in SPLITS for _, s in cfg.episodes(split)]
    assert all(0 <= s <= MAX_SEED for s in seeds)
    assert len(set(seeds)) == len(seeds)  # splits never share a seed


@settings(max_examples=300, deadline=None)
@given(text=st.one_of(st.text(max_size=12), st.integers().map(str), st.floats().map(str)))
def test_option_types_accept_exactly_their_range(text):
    for lo, hi in ((0, MAX_SEED), (1, None), (0, 15)):
        parse = int_in(lo, hi)
        try:
            v = parse(text)
        except argparse.ArgumentTypeError as e:
            assert "\n" not in str(e)
            continue
        assert v == int(text) and lo <= v and (hi is None or v <= hi)
    try:
        positive = float_in(0, above=True)(text)  # a time limit (--episode-timeout)
    except argparse.ArgumentTypeError as e:
        assert "\n" not in str(e)
    else:
        assert math.isfinite(positive) and positive > 0
    try:
        f = float_in(0)(text)
    except argparse.ArgumentTypeError:
        return
    assert math.isfinite(f) and f >= 0


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    s=st.floats(min_value=-5_000.0, max_value=5_000.0, allow_nan=False),
    d=st.floats(min_value=-8.0, max_value=8.0, allow_nan=False),
)
def test_road_frame_round_trip(road, s, d):
    """(s, d) -> xy -> (s, d) within 1 mm on the lanes and shoulders (|d| <= 8 m), s modulo the lap."""
    x, y = road.to_xy(np.array(s), np.array(d))
    s2, d2 = road.to_frenet(x, y)
    lap = road.lap_length
    ds = (float(s2) - s) % lap
    assert min(ds, lap - ds) < 1e-3
    assert abs(float(d2) - d) < 1e-3
    x2, y2 = road.to_xy(s2, d2)
    assert math.hypot(float(x2) - float(x), float(y2) - float(y)) < 1e-3


# --------------------------------------------------------------------------- aggregates and env inputs


class _Folder:
    """What AggregateDataset reads of a dataset folder (pure logic: its manifest, path and episodes)."""

    def __init__(self, path: str, manifest: dict):
        self.path, self.manifest = path, manifest
        self.splits = list(manifest["splits"])

    def episodes(self, split: str) -> list[int]:
        return list(self.manifest["splits"][split])


_MANIFESTS = st.builds(
    lambda seeds, n: {
        "schema_version": 2,
        "feature_names": ["f"],
        "config": {"planner": {"n_policies": 8}},
        "seeds": {"train": seeds, "validation": [s + 1 for s in seeds[:n]]},
        "splits": {"train": list(range(len(seeds))), "validation": list(range(min(n, len(seeds))))},
    },
    st.lists(st.integers(0, MAX_SEED - 1), min_size=1, max_size=4, unique=True),
    st.integers(0, 3),
)


@settings(max_examples=200, deadline=None)
@given(
    manifests=st.lists(_MANIFESTS, min_size=2, max_size=4),
    paths=st.lists(st.text(min_size=1, max_size=12), min_size=4, max_size=4),
    other=st.lists(st.text(min_size=1, max_size=12), min_size=4, max_size=4),
)
def test_an_aggregates_identity_is_its_members_identities_in_order(manifests, paths, other):
    from irlsim.data.aggregate import AggregateDataset, aggregate_identity, manifest_identity
    from irlsim.train.checkpoint import dataset_identity, dataset_seeds, legacy_identities

    def agg(order, names):
        return AggregateDataset([_Folder(names[i], manifests[i]) for i in order])

    order = list(range(len(manifests)))
    a = agg(order, paths)
    # paths never matter (copied, moved, relative): only the members' identities in order
    assert dataset_identity(a) == dataset_identity(agg(order, other))
    assert dataset_identity(a) == aggregate_identity([manifest_identity(m) for m in manifests])
    assert dataset_identity(a) not in legacy_identities(a)
    # every member's seeds are recorded (drive refuses them)
    assert dataset_seeds(a) == sorted({s for m in manifests for v in m["seeds"].values() for s in v})
    reversed_ = agg(order[::-1], paths)
    same = [manifest_identity(m) for m in manifests] == [manifest_identity(m) for m in manifests[::-1]]
    assert (dataset_identity(reversed_) == dataset_identity(a)) == same


_ACTIONS = st.one_of(
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.booleans(),
    st.text(max_size=3),
    st.lists(st.floats(allow_nan=True), max_size=3),
    st.integers(-5, 20).map(np.int64),
    st.integers(0, 20).map(np.uint8),
    st.floats(-5, 5).map(np.float32),
    st.lists(st.integers(0, 9), min_size=0, max_size=3).map(np.array),
)


@settings(max_examples=400, deadline=None)
@given(action=_ACTIONS, n=st.integers(1, 16))
def test_any_discrete_action_is_a_policy_index_or_one_line(action, n):
    from irlsim.envs.planning import discrete_index

    integral = isinstance(action, (int, np.integer)) and not isinstance(action, (bool, np.bool_))
    integral = integral or (
        isinstance(action, np.ndarray) and action.shape == () and action.dtype.kind in "iu"
    )
    try:
        index = discrete_index(action, n)
    except IrlsimError as e:
        assert "\n" not in str(e)
        assert not integral or not 0 <= int(action) < n
    else:
        assert integral and index == int(action) and 0 <= index < n


@settings(max_examples=400, deadline=None)
@given(
    action=st.one_of(
        _ACTIONS, st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=2, max_size=2)
    )
)
def test_any_continuous_action_is_two_finite_numbers_or_one_line(action):
    from irlsim.envs.planning import continuous_action

    try:
        a = continuous_action(action)
    except IrlsimError as e:
        assert "\n" not in str(e)
    else:
        assert a.shape == (2,) and np.isfinite(a).all()
        assert np.array_equal(a, np.asarray(action, dtype=np.float64))


@settings(max_examples=300, deadline=None)
@given(theta=st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=0, max_size=17))
def test_any_theta_is_finite_weights_or_one_line(theta):
    from irlsim import N_FEATURES
    from irlsim.envs.planning import check_theta

    try:
        out = check_theta(np.asarray(theta, dtype=np.float64), "r")
    except IrlsimError as e:
        assert "\n" not in str(e)
        assert len(theta) != N_FEATURES or not np.isfinite(theta).all()
    else:
        assert out.shape == (N_FEATURES,) and np.isfinite(out).all()
