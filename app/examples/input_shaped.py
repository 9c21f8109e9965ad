"""The worked examples of POST /v1/profiles/input-shaped (its OpenAPI examples; the warm-up designs them)."""

from __future__ import annotations

from typing import Any

from app.examples import CHATLATANAGULCHAI_EQ3

_PAPER = {
    "plant": CHATLATANAGULCHAI_EQ3,
    "shaper": "zvd",
    "target_velocity": 1.0,
    "limits": {"max_acceleration": 0.1},
}

EXAMPLES: dict[str, dict[str, Any]] = {
    "paper_modified_zvd": {
        "summary": "Sec. 4: ZVD with the modified baseline, unit velocity, a = 0.1 (Fig. 8 bottom)",
        "description": "The eq. (3) plant (omega_n = 0.57703 rad/s, zeta = 0.057724). ZVD amplitudes (0.2973, 0.4959, "
        "0.2068) at (0, 5.4535, 10.9071) s from the exact poles; Delta = a1 max A_i / a = 4.959 s. The shaped "
        "command passes the limiter unchanged and the residual of x1 vanishes.",
        "value": {**_PAPER, "baseline": "modified", "horizon_s": 60.0, "sample_period_s": 0.05},
    },
    "paper_step_zvd": {
        "summary": "Sec. 3.2: the plain ZVD-shaped step, distorted by the limit a = 0.1 (Fig. 6)",
        "description": "The drive's limiter turns the staircase into ramps of slope 0.1 and the residual returns.",
        "value": {**_PAPER, "baseline": "step", "horizon_s": 60.0, "sample_period_s": 0.05},
    },
    "paper_two_step_zv": {
        "summary": "Fig. 10: ZV with the two-step baseline (the paper's relations hold: A1 > A2)",
        "value": {**_PAPER, "shaper": "zv", "baseline": "multi_step", "horizon_s": 60.0, "sample_period_s": 0.05},
    },
    "rest_to_rest_ei": {
        "summary": "A rest-to-rest move of 10 m with an EI shaper (5 % tolerance) on the eq. (3) plant",
        "value": {
            **{k: v for k, v in _PAPER.items() if k != "target_velocity"},
            "shaper": "ei",
            "displacement": 10.0,
            "sensitivity": {"min_ratio": 0.5, "max_ratio": 1.5, "count": 101},
        },
    },
}
