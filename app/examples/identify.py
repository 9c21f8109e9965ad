"""POST /v1/identify's worked examples: a free vibration of Biagiotti's Sec. VI plant (JSON) and an
accelerometer record (CSV)."""

from __future__ import annotations

from typing import Any

import numpy as np

from app.examples import OMEGA_RAD_S, SIGMA_1_S


def _synthetic_record() -> dict[str, list[float]]:
    """0.3 s of the identified mode's free vibration at 1 kHz: 4 N e^(sigma t) cos(Omega t) + 0.5 N."""
    t = np.arange(301) * 1e-3
    y = 4.0 * np.exp(SIGMA_1_S * t) * np.cos(OMEGA_RAD_S * t) + 0.5
    return {"time_s": [round(float(v), 6) for v in t], "signal": [round(float(v), 6) for v in y]}


EXAMPLES: dict[str, dict[str, Any]] = {
    "biagiotti_free_vibration": {
        "summary": "Sec. V-A / VI: a free vibration of the identified plant",
        "description": "A synthesised spring-force record of the Sec. VI plant (sigma = -15.6539 1/s, "
        "Omega = 122.7185 rad/s) over 0.3 s at 1 kHz; the fit returns them and the tuned smoother T = 0.0768 s.",
        "value": _synthetic_record(),
    }
}


def _csv_example() -> str:
    """0.4 s at 1 kHz of an accelerometer on a 40 Hz mode (zeta 0.02) seen by x and y, with gravity on z and
    noise of std 0.01 (seeded): a complete record that POST /v1/identify fits."""
    t = np.arange(400) * 1e-3
    wn = 2 * np.pi * 40.0
    mode = np.exp(-0.02 * wn * t) * np.cos(wn * np.sqrt(1 - 0.02**2) * t)
    noise = 0.01 * np.random.default_rng(0).standard_normal((3, t.size))
    columns = np.vstack([t, 0.8 * mode + noise[0], 0.3 * mode + noise[1], 9.81 + noise[2]]).T
    rows = "\n".join(f"{a:.3f},{x:.4f},{y:.4f},{z:.4f}" for a, x, y, z in columns)
    return "time_s,accel_x,accel_y,accel_z\n" + rows + "\n"


CSV_EXAMPLE = _csv_example()


def _klipper_psd_example() -> str:
    """Klipper's resonance CSV (TEST_RESONANCES' columns and number formats, its 3200 Hz accelerometer's 1.5625 Hz
    bins up to 200 Hz) of an axis with modes at 42 Hz (zeta 0.07) and 71 Hz (zeta 0.10), as a resonance test
    excites it: a chirp's acceleration, proportional to f, through the base-excited modes, on x and a twentieth of
    it on y, plus a floor of 100 (mm/s^2)^2/Hz on every axis."""
    f = np.arange(129) * 3200.0 / 2048.0
    s = 2j * np.pi * f
    h = np.zeros_like(s)
    for fn, zeta, share in ((42.0, 0.07, 0.6), (71.0, 0.10, 0.4)):
        w = 2 * np.pi * fn
        h += share * (2 * zeta * w * s + w * w) / (s * s + 2 * zeta * w * s + w * w)
    x = 2.0 * (f / 10.0) ** 2 * np.abs(h) ** 2 * (f >= 5.0) + 100.0
    y, z = x / 20.0 + 100.0, np.full_like(f, 100.0)
    rows = "\n".join(f"{a:.1f},{b:.3e},{c:.3e},{d:.3e},{b + c + d:.3e}" for a, b, c, d in zip(f, x, y, z, strict=True))
    return "freq,psd_x,psd_y,psd_z,psd_xyz\n" + rows + "\n"


KLIPPER_PSD_EXAMPLE = _klipper_psd_example()
