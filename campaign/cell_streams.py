"""Many Monte-Carlo cells' random streams at once, each exactly numpy's
`default_rng(SeedSequence(seed))` for its own integer seed.

Building a SeedSequence and a PCG64 per cell costs about 25 µs, half of a
trial study's time. numpy has no batch form, so this module computes the
same seeding arithmetic for all cells as uint32 arrays, then points one
reused Generator at each cell's PCG64 state in turn (a few µs).

SeedSequence (O'Neill's seed_seq as numpy implements it, pool of 4 uint32
words, all products modulo 2³², x ≫ 16 the XSHIFT):

    hashmix(v):  v ← (v ⊕ c_A) · c_A',  c_A ← c_A · M_A,  v ← v ⊕ (v ≫ 16)
                 (c_A' the constant after the update, c_A from I_A)
    mix(x, y):   r = L x - R y,  r ⊕ (r ≫ 16)
    pool_i = hashmix(e_i) for i < 4 (e the seed's 32-bit words, low first,
             0 beyond them); then for every ordered pair src ≠ dst:
             pool_dst ← mix(pool_dst, hashmix(pool_src))
    state words w_j = hashmix_B(pool_(j mod 4)), j < 8, with c_B from I_B, M_B.

PCG64 (128-bit LCG, multiplier m): from w as four uint64 words (s_hi, s_lo,
i_hi, i_lo), inc = 2 i + 1, state = ((0 · m + inc) + s) · m + inc, mod 2¹²⁸.

Seeds here are below 2⁶⁴ (two words), as SeedSequence is given them by
`campaign.trials.draws`. `matches_numpy` checks the arithmetic against
numpy's own objects once per process; a numpy whose seeding differs gets
numpy's slow path, never different numbers.
"""

from functools import lru_cache

import numpy as np

_U32 = np.uint32
INIT_A, MULT_A = _U32(0x43B0D7E5), _U32(0x931E8875)
INIT_B, MULT_B = _U32(0x8B51F9DD), _U32(0x58F38DED)
MIX_L, MIX_R = _U32(0xCA01F9DD), _U32(0x4973F715)
POOL = 4
PCG_MULT = 0x2360ED051FC65DA44385DF649FCCF645
MASK128 = (1 << 128) - 1


def _constants(init, mult, n):
    """The hash constants before and after each of n updates c ← c · mult."""
    c = [init]
    for _ in range(n):
        c.append(_U32(int(c[-1]) * int(mult) & 0xFFFFFFFF))
    return c


def _hash(v, before, after):
    """hashmix of the array v with the constant `before` (`after` its update)."""
    v = (v ^ before) * after
    return v ^ (v >> _U32(16))


def _mix(x, y):
    r = MIX_L * x - MIX_R * y
    return r ^ (r >> _U32(16))


def pools(seeds):
    """SeedSequence(seed).pool of every seed (N, 4), uint32."""
    seeds = np.asarray(seeds, np.uint64)
    words = [(seeds & np.uint64(0xFFFFFFFF)).astype(_U32), (seeds >> np.uint64(32)).astype(_U32)]
    words += [np.zeros_like(words[0])] * (POOL - 2)
    c = _constants(INIT_A, MULT_A, POOL + POOL * (POOL - 1))
    with np.errstate(over="ignore"):
        pool = [_hash(words[i], c[i], c[i + 1]) for i in range(POOL)]
        n = POOL
        for src in range(POOL):
            for dst in range(POOL):
                if src != dst:
                    pool[dst] = _mix(pool[dst], _hash(pool[src], c[n], c[n + 1]))
                    n += 1
    return np.stack(pool, axis=1)


def pcg64_states(seeds):
    """(state, inc) of PCG64(SeedSequence(seed)) for every seed, as Python ints."""
    pool = pools(seeds)
    c = _constants(INIT_B, MULT_B, 2 * POOL)
    with np.errstate(over="ignore"):
        words = np.stack([_hash(pool[:, j % POOL], c[j], c[j + 1]) for j in range(2 * POOL)], axis=1)
    out = []
    for w in np.ascontiguousarray(words).view(np.uint64).tolist():
        s_hi, s_lo, i_hi, i_lo = w
        inc = (((i_hi << 64) | i_lo) << 1 | 1) & MASK128
        state = ((inc + ((s_hi << 64) | s_lo)) * PCG_MULT + inc) & MASK128
        out.append((state, inc))
    return out


def streams(seeds):
    """For each seed in turn, one Generator whose next numbers are exactly
    those of `default_rng(SeedSequence(seed))` (the same Generator object
    each time, re-pointed: draw from it before taking the next)."""
    if not matches_numpy():
        for seed in seeds:
            yield np.random.default_rng(np.random.SeedSequence(int(seed)))
        return
    bits = np.random.PCG64(0)
    rng = np.random.Generator(bits)
    for state, inc in pcg64_states(seeds):
        bits.state = {"bit_generator": "PCG64", "state": {"state": state, "inc": inc},
                      "has_uint32": 0, "uinteger": 0}
        yield rng


@lru_cache(maxsize=1)
def matches_numpy():
    """Whether this module's seeding equals numpy's own for a few seeds."""
    seeds = [0, 1, 0xFFFFFFFF, 1 << 32, 0x0123456789ABCDEF, (1 << 64) - 1]
    ours = pcg64_states(seeds)
    theirs = [np.random.PCG64(np.random.SeedSequence(s)).state["state"] for s in seeds]
    return all(o == (t["state"], t["inc"]) for o, t in zip(ours, theirs))
