"""A campaign's identity is stable: the fast texts behind task ids and the
fingerprint (`schema.task_ids`, `Grid.reprs`, both made by `Grid.texts`
without making a shell) give exactly what the plain json / repr of each
shell's dict gives, and the store's parameter columns (`Grid.columns`)
exactly each shell's values, for the shipped campaigns (dimensionless and
viscous axes among them) and random grids of odd values (tiny, huge and
negative-zero numbers, integers in the file, dimensionless axes); and the
shipped campaigns keep their task ids, and their fingerprints are the shells' texts with the task
kind's name and version (`campaign.kinds`): a store made by another version of the kind is refused."""

import hashlib
import random

import numpy as np
import pytest

from campaign import config
from campaign.store import schema
from conftest import ROOT
from common.errors import InputError

ODD = {"volume_um3": ["4300", "3000.5", "6000"], "h0_um": ["12", "11.5", "10.000000000000002", "14.25"],
       "dh_um": ["0.5", "1", "0.30000000000000004"], "bulk_mN_per_m": ["25.0", "0.0", "-0.0", "1e-300", "3e22"],
       "shear_mN_per_m": ["10.0", "1e-7", "7", "1.7e308"], "tension_mN_per_m": ["1.0", "0.1", "2.5e-5"],
       "thickness_um": ["0.2", "0.15"], "bending": ['"standard"', '"double"', '"none"'],
       "viscosity_Pa_s": ["1.0", "0.0", "2e-3"], "frequency_hz": ["1.0", "10", "0.02"]}
TILDE = {"h0_um": ("h_tilde", ["0.3", "0.45", "0.52"]), "shear_mN_per_m": ("ks_tilde", ["0.3", "1.0", "1e-3"]),
         "tension_mN_per_m": ("gamma_tilde", ["0.02", "0.1"])}


def _random_grids(tmp_path, count, seed):
    """Loaded campaigns of random grids over ODD (some axes dimensionless, some cells viscous)."""
    rng, out = random.Random(seed), []
    for i in range(count):
        viscous, lines = rng.random() < 0.3, ["[grid]"]
        for key, pool in ODD.items():
            if key in ("viscosity_Pa_s", "frequency_hz") and not viscous:
                continue
            name, pool = TILDE[key] if key in TILDE and rng.random() < 0.3 else (key, pool)
            values = rng.sample(pool, rng.randint(1, min(3, len(pool))))
            lines.append(f"{name} = [{', '.join(values)}]" if len(values) > 1 or rng.random() < 0.5 else
                         f"{name} = {values[0]}")
        path = tmp_path / f"odd{i}.toml"
        path.write_text("\n".join(lines) + "\n")
        try:
            out.append(config.load(path))
        except InputError:          # an impossible point: not a grid to compare
            pass
    return out


def _campaigns(tmp_path, seed):
    shipped = [config.load(ROOT / f"campaigns/{name}.toml") for name in ("paper", "demo", "viscosity", "emulator")]
    return shipped + _random_grids(tmp_path, 150, seed)


@pytest.mark.parametrize("method", ["fast", "explicit", 'odd "100%" name'])
def test_task_ids_are_task_id_of_each_shell(tmp_path, method):
    campaigns = _campaigns(tmp_path, seed=len(method))
    assert len(campaigns) > 60 and sum(len(c.shells) for c in campaigns) > 5000
    for c in campaigns:
        assert schema.task_ids(c.shells, method) == [schema.task_id(s, method) for s in c.shells]


def test_fingerprint_texts_are_the_repr_of_each_dict(tmp_path):
    for c in _campaigns(tmp_path, seed=2):
        assert list(c.shells.reprs()) == [repr(s.to_dict()) for s in c.shells]


def test_store_columns_are_each_shells_values_bit_for_bit(tmp_path):
    for c in _campaigns(tmp_path, seed=3):
        columns, shells = c.shells.columns(), list(c.shells)
        for key in schema.PARAMS:
            expected = np.array([np.nan if getattr(s, key) is None else getattr(s, key) for s in shells])
            assert columns[key].dtype == np.float64
            assert expected.tobytes() == columns[key].tobytes(), key        # -0.0 and every last bit
        assert list(columns["bending"]) == [s.bending for s in shells]


def test_the_shipped_campaigns_keep_their_identity():
    paper = config.load(ROOT / "campaigns/paper.toml")
    plain = hashlib.sha256(("[" + ", ".join(repr(s.to_dict()) for s in paper.shells) + "]"
                            + paper.method + repr(paper.resolution) + "compression@1").encode()).hexdigest()
    assert paper.fingerprint == plain == "e40972e6a1380323a16a913fda5a4921f0b537e99fec1131f537c9c15d3d970d"
    ids = list(schema.task_ids(paper.shells, paper.method))
    assert (ids[0], ids[-1]) == ("251b966d954fa5a6", "ccdcc8b09ef93b0a") and len(set(ids)) == 540
    demo = config.load(ROOT / "campaigns/demo.toml")
    assert demo.fingerprint == "7e9c55f3827ac47ca59b0487749d7b87e7c361a8bd19fc66298eea04d98ee85a"
