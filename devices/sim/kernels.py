"""Compiled inner loop of the simulated finger (numba): its friction lagging its law.

Like :mod:`ultraglide.devices.output.kernels`, it takes and fills numpy arrays, returns the state to carry to
the next chunk, and allocates nothing.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def friction_lag(static, speed, force, lifted_n, rate_hz, onset_s, recovery_s, reference_speed, speed_exponent,
                 slowest_speed, felt, out):
    """A finger's friction lagging its settled value: out[i] = s + (felt - s) exp(-1 / (rate tau)), s = static[i],
    tau ``onset_s`` while friction falls and recovery_s (reference_speed / speed[i])^speed_exponent while it rises
    (speeds below ``slowest_speed`` count as it). A lifted finger (force below ``lifted_n``) comes back with its
    friction settled at rest (1). Returns the friction ratio to carry on from."""
    fall = np.exp(-1.0 / (rate_hz * onset_s))
    for i in range(static.shape[0]):
        s = static[i]
        if force[i] < lifted_n:
            felt = 1.0
            out[i] = s
            continue
        if s < felt:
            keep = fall
        else:
            v = speed[i] if speed[i] > slowest_speed else slowest_speed
            keep = np.exp(-1.0 / (rate_hz * recovery_s * (reference_speed / v) ** speed_exponent))
        felt = s + (felt - s) * keep
        out[i] = felt
    return felt
