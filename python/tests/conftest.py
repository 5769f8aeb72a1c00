"""Shared test data: every cloud is made here, from a seed."""
import numpy as np
import pytest

import tessel


def sphere(n, seed=1, noise=0.0, radius=1.0, center=(0.0, 0.0, 0.0)):
    """n points uniformly random on a sphere (float64), plus Gaussian noise."""
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1)[:, None]
    p *= radius
    if noise:
        p += rng.normal(scale=noise, size=p.shape)
    return p + np.asarray(center, dtype=np.float64)


def fibonacci_sphere(n, radius=1.0):
    """n evenly spread points on a sphere (a clean, even sample)."""
    i = np.arange(n) + 0.5
    phi = np.arccos(1.0 - 2.0 * i / n)
    theta = np.pi * (1.0 + 5.0 ** 0.5) * i
    return radius * np.column_stack([np.cos(theta) * np.sin(phi),
                                     np.sin(theta) * np.sin(phi), np.cos(phi)])


def terrain(nx=120, ny=100, step=1.0, seed=3):
    """A height field: jittered grid, gentle hills."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.arange(nx) * step, np.arange(ny) * step)
    x = x + rng.uniform(-0.2, 0.2, x.shape) * step
    y = y + rng.uniform(-0.2, 0.2, y.shape) * step
    z = 3.0 * np.sin(x / 15.0) * np.cos(y / 11.0)
    return np.column_stack([x.ravel(), y.ravel(), z.ravel()])


def organized_scan(h=60, w=80, holes=True):
    """A depth camera at the origin looking down +z at a wall with a box in
    front of it: (H, W, 3) with NaN where nothing was hit."""
    v, u = np.meshgrid(np.linspace(-0.5, 0.5, h), np.linspace(-0.6, 0.6, w), indexing="ij")
    depth = np.full((h, w), 4.0)
    box = (np.abs(u) < 0.2) & (np.abs(v) < 0.2)
    depth[box] = 3.0
    pts = np.stack([u * depth, v * depth, depth], axis=-1)
    if holes:
        pts[5:9, 10:14] = np.nan
    return pts


@pytest.fixture
def clean_sphere():
    return fibonacci_sphere(4000)


@pytest.fixture(scope="session")
def sphere_mesh():
    return tessel.reconstruct(fibonacci_sphere(4000), method="greedy")
