"""SUMO's FCD in SUMO's table formats, with real SUMO: ``sumo --fcd-output x.csv`` (semicolons, or the
separator asked for) and ``x.parquet`` write the same trajectories as the XML under column names of
SUMO's own (``vehicle_x``, or ``x``, or ``timestep_vehicle_x`` by ``--output.column-header``), a row with
the time alone for a step without vehicles. Each is read as the same recording as the XML, and SUMO's
human-readable time is one line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from irlsim.data.recording import load_recording
from irlsim.data.recording_read import read_rows
from irlsim.errors import IrlsimError
from irlsim.road import load_road
from tests.data.conftest import record_fcd

#: how SUMO is asked to write its table (options), by the file's name
TABLES = {
    "fcd.csv": (),
    "fcd.parquet": (),
    "plain.csv": ("--output.column-header", "plain"),
    "full.parquet": ("--output.column-header", "full"),
    "commas.csv": ("--output.column-separator", ","),
}


@pytest.fixture(scope="module")
def late(fcd, tmp_path_factory) -> Path:
    """The fixture's cars departing 5 s after the recording starts (its first steps hold no vehicle)."""
    tmp = tmp_path_factory.mktemp("late")
    routes = (fcd.parent / "cars.rou.xml").read_text()
    for i in range(5):
        routes = routes.replace(f'depart="{2 * i}"', f'depart="{2 * i + 5}"')
    (tmp / "cars.rou.xml").write_text(routes)
    return tmp / "cars.rou.xml"


@pytest.mark.parametrize("name", list(TABLES))
def test_sumos_fcd_tables_are_the_same_recording_as_its_xml(late, tmp_path, name):
    xml = record_fcd(late, tmp_path / "fcd.xml")
    table = record_fcd(late, tmp_path / name, *TABLES[name])
    rows = read_rows(table)
    assert rows.fcd and len(rows.t) == len(read_rows(xml).t)  # the steps without vehicles are no rows
    assert rows.vtype is not None and set(rows.vtype) == {"car"}
    net = load_road().net
    a, b = load_recording(xml, net, 0.1), load_recording(table, net, 0.1)
    assert b.ids == a.ids and b.edges == a.edges and a.t0.min() >= 5.0
    for k in ("x", "y", "v"):  # SUMO writes the same numbers (the XML to 2 decimals, Parquet's floats)
        assert np.allclose(getattr(b, k), getattr(a, k), atol=0.006)
    assert np.allclose(np.sin(b.heading - a.heading), 0.0, atol=1e-3)


@pytest.mark.parametrize(
    "options, needle",
    [
        (("--human-readable-time",), "without --human-readable-time"),
        (("--fcd-output.attributes", "x,y,angle"), "SUMO's FCD output without speed: record it with x, y"),
    ],
)
def test_a_table_sumo_wrote_otherwise_is_one_line(late, tmp_path, options, needle):
    table = record_fcd(late, tmp_path / "other.csv", *options)
    with pytest.raises(IrlsimError) as e:
        load_recording(table, load_road().net, 0.1)
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_a_columnar_file_with_columns_named_like_sumos_is_still_the_columnar_format(fcd, tmp_path):
    from tests.data.test_recording import _columns, _csv

    cols = _columns(fcd)
    cols["vehicle_class"] = ["passenger"] * len(cols["id"])  # an extra column of the user's
    rows = read_rows(_csv(tmp_path / "mine.csv", cols))
    assert not rows.fcd and np.allclose(rows.x, cols["x"])
