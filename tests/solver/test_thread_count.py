"""A frictional frame's verdict and motion do not depend on the number of threads.

The pads squeeze a free ball with no weight: each pad holds it at one node, so nothing
holds its turn about the pads' axis and nothing asks for it. The solve runs in fresh
processes with one and with two threads (PARDISO's and BLAS's round-off differ between
them) and must give the same answer, the ball unturned.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = """
import json, numpy as np, fem
from tests.solver.test_friction import _PADS_MESH, _pads
res, _ = _pads(0.0)
u = res.displacement["ball"]
_, omega = fem.rigid_part(_PADS_MESH.points, u)
print(json.dumps({"converged": bool(res.converged), "reason": res.stop_reason,
                  "omega": [float(x) for x in omega], "u": u.ravel().tolist()}))
"""


def _run(threads: int) -> dict:
    env = dict(os.environ)
    for key in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        env[key] = str(threads)
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT], cwd=ROOT, env=env, capture_output=True, text=True,
        check=True, timeout=300,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_the_pads_squeeze_is_the_same_on_one_and_two_threads():
    one, two = _run(1), _run(2)
    assert one["converged"] and two["converged"], (one["reason"], two["reason"])
    assert one["reason"] == two["reason"]
    assert np.abs(one["omega"]).max() <= 1e-12 and np.abs(two["omega"]).max() <= 1e-12
    u1, u2 = np.array(one["u"]), np.array(two["u"])
    assert np.abs(u1 - u2).max() <= 1e-8 * np.abs(u1).max()
