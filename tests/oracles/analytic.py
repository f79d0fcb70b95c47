"""Analytic echoes and plane waves built independently of the simulator: what the
processing tests feed the pipeline, and the rotation written out by hand."""

import numpy as np

import processing as P


def rotation_zyx(yaw, pitch=0.0, roll=0.0) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) (3, 3), angles in rad, written out independently
    of the package (sensor axes as columns in the world frame)."""
    cy, sy = np.cos(yaw), np.sin(yaw)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def direction(az_deg: float, el_deg: float) -> np.ndarray:
    az, el = np.deg2rad(az_deg), np.deg2rad(el_deg)
    return np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


def echo_recording(
    array,
    sources,
    *,
    fs=500e3,
    c=343.0,
    n_samples=4096,
    waveform=None,
    noise=0.0,
    seed=0,
    emission_index=0,
):
    """Exact echoes of point reflectors [(az_deg, el_deg, range_m, amplitude), ...]."""
    wf = waveform or P.paper_chirp()
    t = (np.arange(n_samples) - emission_index) / fs
    x = np.zeros((array.n_mics, n_samples))
    for az, el, r, amp in sources:
        src = r * direction(az, el)
        d_e = np.linalg.norm(src - array.emitter_m)
        d_m = np.linalg.norm(src[None] - array.positions_m, axis=1)
        tau = (d_e + d_m) / c
        x += amp * wf.at(t[None, :] - tau[:, None])
    if noise:
        x += noise * np.random.default_rng(seed).standard_normal(x.shape)
    return P.Recording(x, fs, array, wf, c, emission_index)


def plane_wave_snapshot(array, az_deg, el_deg, f, c=343.0):
    """The narrow-band snapshot of a far-field source, sign convention of steering.py."""
    k = 2 * np.pi * f / c
    return np.exp(1j * k * array.positions_m @ direction(az_deg, el_deg))
