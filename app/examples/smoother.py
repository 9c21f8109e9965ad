"""The worked examples of POST /v1/profiles/smoother (its OpenAPI examples; the warm-up designs them)."""

from __future__ import annotations

from typing import Any

from app.examples import BIAGIOTTI_DRIVE, BIAGIOTTI_PLANT, T0_S

EXAMPLES: dict[str, dict[str, Any]] = {
    "biagiotti_damped_harmonic": {
        "summary": "Sec. VI: damped harmonic smoother on the identified plant, 30 mm step",
        "description": "sigma = -15.6539 1/s and Omega = 122.7185 rad/s give T0 = 0.0512 s and T1 = 1.5 T0 = 0.0768 s. "
        "The smoother cancels the mode: the residual is zero to round-off. The discrete filter at the "
        "experiment's Ts = 0.5 ms (eq. 17) rounds T1/Ts = 153.6 to 154 samples, which leaves 0.27 % of the "
        "unfiltered vibration; exact_sample_period_s avoids it.",
        "value": {
            "plant": BIAGIOTTI_PLANT,
            "displacement": 0.03,
            "filters": [{"type": "damped_harmonic"}],
            "sample_period_s": 0.0005,
            "discrete_sample_period_s": 0.0005,
            "sensitivity": {"min_ratio": 0.5, "max_ratio": 1.5, "count": 101},
        },
    },
    "biagiotti_through_a_sampled_drive": {
        "summary": "Sec. VI: the damped harmonic smoother through a PID + feed-forward loop sampled every 500 us",
        "description": "closed_loop is the 30 mm move through the drive, at its samples: the loop's lag leaves "
        "about 1 % of the move in residual vibration where the ideal motor leaves none, still 5 times less than "
        "the undamped smoother's (the paper's Fig. 17: 3.6 N against 4.7 N). The gains and the moving mass are "
        "assumed: the paper gives neither.",
        "value": {
            "plant": BIAGIOTTI_PLANT,
            "displacement": 0.03,
            "filters": [{"type": "damped_harmonic"}],
            "sample_period_s": 0.0005,
            "drive": BIAGIOTTI_DRIVE,
        },
    },
    "biagiotti_harmonic": {
        "summary": "Sec. VI: undamped harmonic smoother on the same plant",
        "description": "T = 3 pi/Omega = 0.0768 s, but S cannot cancel a damped mode: about 4.3 % of the 30 mm "
        "step is left (Fig. 17 (d) against (e)).",
        "value": {
            "plant": BIAGIOTTI_PLANT,
            "displacement": 0.03,
            "filters": [{"type": "harmonic"}],
            "sample_period_s": 0.0005,
        },
    },
    "biagiotti_exponential_pair": {
        "summary": "Sec. V: two exponential filters M_sigma,1 M_sigma,2 (T0 and T0/2)",
        "description": "The damped generalisation of M1 M2 with T1 = T0 = 0.0512 s, compared with S_sigma in Fig. 13.",
        "value": {
            "plant": BIAGIOTTI_PLANT,
            "displacement": 0.03,
            "filters": [{"type": "exponential"}, {"type": "exponential", "duration_s": round(T0_S / 2, 10)}],
            "sample_period_s": 0.0005,
        },
    },
    "limits_and_vibration": {
        "summary": "Damped harmonic smoother under velocity and acceleration limits",
        "description": "Rectangular filters are put in front of the tuned smoother so that |v| <= 0.3 m/s and "
        "|a| <= 10 m/s^2 (eqs. 2-3 extended to the chain); the mode stays cancelled.",
        "value": {
            "plant": BIAGIOTTI_PLANT,
            "displacement": 0.03,
            "filters": [{"type": "damped_harmonic"}],
            "limits": {"max_velocity": 0.3, "max_acceleration": 10.0},
            "sample_period_s": 0.0005,
        },
    },
    "kinematic_chain": {
        "summary": "Sec. II: time-optimal chain for v = 1, a = 2, j = 8 and h = 1",
        "description": "No vibration filter: three rectangular filters T = (1, 0.5, 0.25) s (eq. 2; eq. 3 holds).",
        "value": {
            "plant": BIAGIOTTI_PLANT,
            "displacement": 1.0,
            "filters": [],
            "limits": {"max_velocity": 1.0, "max_acceleration": 2.0, "max_jerk": 8.0},
            "sample_period_s": 0.01,
        },
    },
}
