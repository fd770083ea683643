"""Cell volumes from what an image measures: the confined droplet of a given
height and equatorial radius (`cortex geometry --equator-radius`,
`solver.geometry.volume_from_image`), and volume tables that give an
equatorial radius with the imaged height, or the free cell's diameter."""

import json

import numpy as np
import pandas as pd
import pytest

from analysis.afm.formats.instruments import read_volumes
from cortex.cli import main
from common.errors import EXIT_BAD_INPUT, InputError
from solver.geometry import droplet, volume_from_image


def test_the_paper_cell_from_its_height_and_equator(capsys):
    assert main(["geometry", "--height", "12", "--equator-radius", "11.7969", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)
    assert row["volume_um3"] == pytest.approx(4300.0, rel=1e-4)
    assert row["equator_radius_um"] == pytest.approx(11.7969, rel=1e-12)


@pytest.mark.parametrize("volume,height", [(4300.0, 14.0), (4300.0, 10.0), (1000.0, 12.0), (9000.0, 6.0)])
def test_inverts_the_droplet_of_given_volume(volume, height):
    r_eq = float(droplet(volume, height).equator_radius_um)
    assert volume_from_image(height, r_eq) == pytest.approx(volume, rel=1e-9)


def test_the_free_sphere_and_impossible_shapes():
    assert volume_from_image(20.0, 10.0) == pytest.approx(4 / 3 * np.pi * 1000.0, rel=1e-12)
    for h, r in ((21.0, 10.0), (0.1, 10.0), (0.0, 10.0), (12.0, -1.0), (float("nan"), 10.0)):
        with pytest.raises(InputError):
            volume_from_image(h, r)


def test_geometry_needs_a_volume_or_an_equator_radius(capsys):
    assert main(["geometry", "--height", "12"]) == EXIT_BAD_INPUT
    assert main(["geometry", "--height", "12", "--volume", "4300", "--equator-radius", "11"]) == EXIT_BAD_INPUT
    assert main(["geometry", "--height", "30", "--equator-radius", "11"]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and "exceeds twice the equator radius" in err[-1]


def test_a_table_of_volumes_radii_and_diameters(tmp_path):
    path = tmp_path / "v.csv"
    pd.DataFrame({"cell_id": ["a", "b", "c", "d"], "volume_um3": [4000.0, None, None, 5000.0],
                  "equator_radius_um": [None, 11.7969, None, 11.0], "imaged_height_um": [None, 12.0, None, 12.0],
                  "diameter_um": [None, None, 20.0, None],
                  "volume_source": ["confocal", "brightfield", None, None]}).to_csv(path, index=False)
    t = read_volumes(path)
    assert t["a"] == (4000.0, "confocal")
    assert t["b"][0] == pytest.approx(4300.0, rel=1e-4)
    assert t["b"][1] == "brightfield: equator radius 11.7969 um at imaged height 12 um (table v.csv)"
    assert t["c"] == (pytest.approx(np.pi * 20.0**3 / 6), "free-cell diameter 20 um (table v.csv)")
    assert t["d"] == (5000.0, "table v.csv")                                   # a volume comes first


@pytest.mark.parametrize("frame,message", [
    ({"cell_id": ["a"], "equator_radius_um": [11.0]}, "needs the column imaged_height_um"),
    ({"cell_id": ["a"], "diameter_um": [-3.0]}, "has no positive"),
    ({"cell_id": ["a"], "equator_radius_um": [5.0], "imaged_height_um": [12.0]}, "exceeds twice"),
    ({"cell_id": ["a"], "height_um": [5.0]}, "columns cell_id and one of"),
])
def test_a_bad_table_is_one_line(tmp_path, frame, message):
    path = tmp_path / "v.csv"
    pd.DataFrame(frame).to_csv(path, index=False)
    with pytest.raises(InputError, match=message):
        read_volumes(path)
