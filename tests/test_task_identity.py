"""A campaign's identity is stable: the fast texts behind task ids and the
fingerprint (templates, `schema.task_ids`, `model.dict_texts`) give exactly
what the plain json / repr of each shell's dict gives, for campaign shells
and for odd ones (ints, numpy floats, -0.0, extreme exponents, an explicit
bending stiffness, viscous cells), and the shipped campaigns keep the ids and
fingerprints their stores were made with (so those stores still resume)."""

import hashlib
import random

import numpy as np
import pytest

from campaign import config, schema
from conftest import ROOT
from solver.errors import InputError
from solver.model import Shell, dict_texts


def _odd_shells(count=4000, seed=1):
    rng, out = random.Random(seed), []
    for _ in range(count):
        kw = dict(volume_um3=rng.choice([4300.0, 4300, np.float64(4300.0), 3000 + 1e3 * rng.random()]),
                  h0_um=rng.choice([12.0, 12, np.float64(11.5), 10 + 5 * rng.random()]),
                  bulk_mN_per_m=rng.choice([25.0, 0.0, -0.0, 1e-300, 3e22, 25, True, 1.7e308]),
                  shear_mN_per_m=rng.choice([10.0, 1e-7, 7, 1.7e308]),
                  tension_mN_per_m=rng.choice([1.0, 0.1 + rng.random()]),
                  bending=rng.choice(["standard", "double", "none"]),
                  bending_pN_um=rng.choice([None, 0.0, 12.5, np.float64(3.0), 2]))
        if rng.random() < 0.3:
            kw.update(viscosity_Pa_s=rng.choice([1.0, 0.0, np.float64(2.0)]), frequency_hz=rng.choice([1.0, 10]))
        try:
            out.append(Shell(**kw))
        except InputError:
            pass
    return out


@pytest.mark.parametrize("method", ["fast", "explicit", 'odd "100%" name'])
def test_task_ids_are_task_id_of_each_shell(method):
    shells = _odd_shells() + list(config.load(ROOT / "campaigns/viscosity.toml").shells)
    assert len(shells) > 3000
    assert list(schema.task_ids(shells, method)) == [schema.task_id(s, method) for s in shells]


def test_dict_texts_are_the_repr_of_each_dict():
    shells = _odd_shells(seed=2) + list(config.load(ROOT / "campaigns/viscosity.toml").shells)
    assert list(dict_texts(shells)) == [repr(s.to_dict()) for s in shells]


def test_the_shipped_campaigns_keep_their_identity():
    paper = config.load(ROOT / "campaigns/paper.toml")
    plain = hashlib.sha256(("[" + ", ".join(repr(s.to_dict()) for s in paper.shells) + "]"
                            + paper.method + repr(paper.resolution)).encode()).hexdigest()
    # the values the stores made before these templates hold
    assert paper.fingerprint == plain == "0a37acfe8396efbc0dd892b28aa162020d5d510b5995b052111ee4439f65abae"
    ids = list(schema.task_ids(paper.shells, paper.method))
    assert (ids[0], ids[-1]) == ("251b966d954fa5a6", "ccdcc8b09ef93b0a") and len(set(ids)) == 540
    demo = config.load(ROOT / "campaigns/demo.toml")
    assert demo.fingerprint == "97d61b86ee3e16eb7ae5de3b6d01029b0ca90fe255d46ea7ae34cddfb45c166f"
