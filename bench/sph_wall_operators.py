#!/usr/bin/python3
"""The sph_solver's wall terms on a boulder, checked offline against an exact flow.

A sphere of radius R sampled as the boundary_particles pair samples it (three shells of
golden-angle points, libsabo/geometry/sphere_sampling.cpp) translates at U through fluid whose
particles sit on spherical shells at R + (k + 1/2) dx (the layering the fluid settles into around
a sphere) and carry Stokes' exact creeping flow and pressure. The force on the sphere is summed
from the wall pairs as the sph_solver sums it (sph_solver/passes/pair_terms.hpp: Morris's viscous
term against the wall particle's no-slip velocity, the pressure term against its extrapolated
pressure; Wendland C2 kernel at h = 1.5 dx) and compared with Stokes' viscous 4 pi mu R U and
pressure 2 pi mu R U. Nothing is integrated in time: the flow is exact, so what is off is the wall
terms' own discretisation, one choice at a time:

  --velocity adami   the no-slip velocity 2 v_w - v~, v~ the kernel average of the fluid around
                     the wall particle (Adami et al. 2012 eq. 22; what the sph_solver does)
  --velocity mirror  2 v_w - v(x_g), v(x_g) the kernel average at the wall particle's mirror point
                     across the surface (fixed ghost points, Marrone et al. 2011)
  --velocity mirror_linear  2 v_w - v(x_g), v(x_g) fitted to first order (weighted least squares in
                     the kernel) at the mirror point: exact for a linear flow, where the kernel average
                     at a mirror point beside the fluid's edge is biased away from the wall
  --velocity exact   Stokes' solution continued into the sphere
  --pressure adami   the kernel average of the fluid's pressure (Adami eq. 27 without gravity)
  --pressure mirror  the fluid's pressure and its gradient fitted to first order (weighted least squares
                     in the kernel) at the mirror point, continued linearly to the wall particle
  --pressure exact   Stokes' pressure continued to the wall particle

Needs Debian's python3-numpy. Prints one line per diameter.
"""
import argparse
import math

import numpy as np

GOLDEN = math.pi * (3.0 - math.sqrt(5.0))


def shells(radii, dx, turn):
    points, volumes = [], []
    for k, shell in enumerate(radii):
        if shell <= 0:
            continue
        inner, outer = max(0.0, shell - 0.5 * dx), shell + 0.5 * dx
        count = max(1, round(4 * math.pi * shell * shell / (dx * dx)))
        volume = 4.0 / 3.0 * math.pi * (outer ** 3 - inner ** 3) / count
        i = np.arange(count)
        z = 1 - 2 * (i + 0.5) / count if count > 1 else np.ones(1)
        r = np.sqrt(np.maximum(0.0, 1 - z * z))
        phi = turn * k + GOLDEN * i
        points.append(shell * np.stack([r * np.cos(phi), r * np.sin(phi), z], 1))
        volumes.append(np.full(count, volume))
    return np.concatenate(points), np.concatenate(volumes)


def wendland(r, h):
    q = r / h
    return np.where(q < 2, 21 / (16 * math.pi * h ** 3) * (1 - q / 2) ** 4 * (2 * q + 1), 0.0)


def gradient_factor(r, h):  # (1/r) dW/dr
    q = r / h
    return np.where(q < 2, 21 / (16 * math.pi * h ** 3) * (-5 * q) * (1 - q / 2) ** 3 / h / np.maximum(r, 1e-300),
                    0.0)


def stokes(x, radius, mu, u):
    r = np.linalg.norm(x, axis=1)[:, None]
    ux = (x @ u)[:, None]
    velocity = 0.75 * radius * (u / r + ux * x / r ** 3) + 0.25 * radius ** 3 * (u / r ** 3 - 3 * ux * x / r ** 5)
    pressure = 1.5 * mu * radius * (x @ u) / r[:, 0] ** 3
    return velocity, pressure


def forces(diameter_spacings, velocity_mode, pressure_mode, dx=0.01, mu=10.0, rho=1000.0):
    radius, h = 0.5 * diameter_spacings * dx, 1.5 * dx
    support = 2 * h
    u = np.array([0.0, 0.0, -0.01])
    fluid, fluid_volume = shells([radius + (k + 0.5) * dx for k in range(8)], dx, 0.37)
    wall, wall_volume = shells([radius - (k + 0.5) * dx for k in range(3)], dx, 0.5 * GOLDEN)
    v, p = stokes(fluid, radius, mu, u)

    def fit(point, values):
        offset = fluid - point
        w = wendland(np.linalg.norm(offset, axis=1), h)
        a = np.hstack([np.ones((len(fluid), 1)), offset])
        return np.linalg.solve((a * w[:, None]).T @ a, (a * w[:, None]).T @ values)

    def mirror(x_b):
        depth = radius - np.linalg.norm(x_b)
        return x_b + 2 * depth * x_b / np.linalg.norm(x_b)

    def average(point, values):
        r = np.linalg.norm(fluid - point, axis=1)
        w = wendland(r, h)
        return (w[:, None] * values).sum(0) / w.sum() if values.ndim > 1 else (w * values).sum() / w.sum()

    viscous, pressure = np.zeros(3), np.zeros(3)
    for b, x_b in enumerate(wall):
        rv = fluid - x_b
        r = np.linalg.norm(rv, axis=1)
        near = r < support
        if not near.any():
            continue
        rv, r = rv[near], r[near]
        f = gradient_factor(r, h)
        if velocity_mode == "adami":
            v_b = 2 * u - average(x_b, v)
        elif velocity_mode == "mirror":
            v_b = 2 * u - average(mirror(x_b), v)
        elif velocity_mode == "mirror_linear":
            v_b = 2 * u - fit(mirror(x_b), v)[0]
        else:
            v_b = stokes(x_b[None, :], radius, mu, u)[0][0]
        if pressure_mode == "adami":
            p_b = average(x_b, p)
        elif pressure_mode == "mirror":
            x_g = mirror(x_b)
            coefficients = fit(x_g, p)
            p_b = coefficients[0] + coefficients[1:] @ (x_b - x_g)
        else:
            p_b = stokes(x_b[None, :], radius, mu, u)[1][0]
        m_i = rho * fluid_volume[near]
        # The force on fluid particle i from wall particle b; the wall particle takes minus it.
        viscous -= ((m_i * wall_volume[b] * 2 * mu / rho * f)[:, None] * (v[near] - v_b)).sum(0)
        pressure -= (-(m_i * rho * wall_volume[b] * (p[near] + p_b) / rho ** 2 * f)[:, None] * rv).sum(0)
    scale = 6 * math.pi * mu * radius * abs(u[2])
    return abs(viscous[2]) / scale, abs(pressure[2]) / scale


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--diameters", type=float, nargs="+", default=[6, 10, 20], help="D / dx")
    parser.add_argument("--velocity", choices=["adami", "mirror", "mirror_linear", "exact"], default="adami")
    parser.add_argument("--pressure", choices=["adami", "mirror", "exact"], default="adami")
    args = parser.parse_args()
    for d in args.diameters:
        viscous, pressure = forces(d, args.velocity, args.pressure)
        print("D = {:g} dx, velocity {}, pressure {}: viscous {:.3f} (Stokes 0.667), pressure {:.3f} (0.333), "
              "total {:.3f} of 6 pi mu R U".format(d, args.velocity, args.pressure, viscous, pressure,
                                                    viscous + pressure))


if __name__ == "__main__":
    main()
