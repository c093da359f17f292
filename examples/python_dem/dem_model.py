"""The physics of the reference DEM solver: spheres under gravity, a linear spring-dashpot between
touching spheres, and the contact forces and torques the coupler sends, integrated by central
differences. No protocol here (sabo_wire.py, solver.py): this module can be tested on its own.

What it models, and what it leaves out on purpose (it is a reference of the protocol, not a second
dem_solver):
  * sphere-sphere contacts: the normal spring-dashpot of [contact.dem_dem] (normal_stiffness or
    normal_stiffness_scale, normal_damping_ratio, per-pair normal_damping_ratio); no tangential
    spring, no friction, no rolling resistance between spheres (they are logged as ignored);
  * rotation under the torques the coupler sends (DEM-FEM friction), I = 2/5 m r^2;
  * `[[particles]]` sets given as explicit `spheres` lists (the random `fill` is refused), `fixed` sets.
The all-pairs contact search is O(N^2): fine for a few hundred spheres.
"""
import math

import numpy as np


class SceneError(Exception):
    """The scene asks for something this solver cannot do; the message names the key and the fix."""


def _table(scene, key):
    value = scene.get(key, {})
    if not isinstance(value, dict):
        raise SceneError("[{}] must be a table".format(key))
    return value


class DemModel:
    """Spheres of a scene. Arrays are (N, 3) float64; index i is the sphere's id and its row in the
    particle table sent at registration."""

    def __init__(self, scene, scene_file="scene"):
        run = _table(scene, "run")
        self.gravity = np.array(run.get("gravity", [0.0, 0.0, -9.81]), dtype=np.float64)
        materials = _table(scene, "materials")
        material_names = sorted(materials)  # the protocol's material index: materials sorted by name
        contact = _table(scene, "contact").get("dem_dem", {})
        self.ignored = [key for key in ("friction", "rolling", "rolling_friction", "rolling_viscosity",
                                        "tangential_damping_ratio", "tangential_stiffness_ratio") if key in contact]
        if contact.get("model", "linear") != "linear":
            raise SceneError("{}: [contact.dem_dem] model = {!r}: this solver has the linear law only. Fix: "
                             "model = \"linear\", or run the built dem_solver".format(scene_file, contact["model"]))
        if "normal_stiffness" in contact and "normal_stiffness_scale" in contact:
            raise SceneError("{}: [contact.dem_dem] gives both normal_stiffness and normal_stiffness_scale. "
                             "Fix: keep one".format(scene_file))
        self.normal_stiffness = contact.get("normal_stiffness")
        self.stiffness_scale = contact.get("normal_stiffness_scale", 0.01)
        default_damping = contact.get("normal_damping_ratio", 0.7)

        centers, velocities, spins, radii, material, body, fixed = [], [], [], [], [], [], []
        for set_index, particle_set in enumerate(scene.get("particles", [])):
            where = "{}: [[particles]] {!r}".format(scene_file, particle_set.get("name", set_index))
            if "spheres" not in particle_set:
                raise SceneError("{}: this solver places only explicit `spheres` lists (no `fill`). Fix: list "
                                 "the spheres, or run the built dem_solver".format(where))
            name = particle_set.get("material")
            if name not in materials:
                raise SceneError("{}: material {!r} is not a [materials.NAME]. Fix: one of {}".format(
                    where, name, ", ".join(material_names)))
            for sphere in particle_set["spheres"]:
                centers.append(sphere["center"])
                velocities.append(sphere.get("velocity", [0.0, 0.0, 0.0]))
                spins.append(sphere.get("angular_velocity", [0.0, 0.0, 0.0]))
                radii.append(float(sphere["radius"]))
                material.append(material_names.index(name))
                body.append(set_index)
                fixed.append(bool(particle_set.get("fixed", False)))
        self.position = np.array(centers, dtype=np.float64).reshape(-1, 3)
        self.velocity = np.array(velocities, dtype=np.float64).reshape(-1, 3)
        self.spin = np.array(spins, dtype=np.float64).reshape(-1, 3)
        self.radius = np.array(radii, dtype=np.float64)
        self.material = np.array(material, dtype=np.uint32)
        self.body = np.array(body, dtype=np.uint32)
        self.fixed = np.array(fixed, dtype=bool)
        density = np.array([materials[material_names[m]]["density"] for m in material], dtype=np.float64)
        self.mass = density * (4.0 / 3.0 * math.pi) * self.radius ** 3
        self.inertia = 0.4 * self.mass * self.radius ** 2
        bulk = [materials[n]["youngs_modulus"] / (3.0 * (1.0 - 2.0 * materials[n].get("poisson_ratio", 0.3)))
                for n in material_names]
        self.stiffness_term = np.array([bulk[m] for m in material], dtype=np.float64) * self.radius
        # Normal damping ratio per pair of materials (a symmetric table).
        self.damping_ratio = np.full((len(material_names),) * 2, default_damping)
        for pair in contact.get("pairs", []):
            a, b = (material_names.index(n) for n in pair["materials"])
            ratio = pair.get("normal_damping_ratio", default_damping)
            self.damping_ratio[a, b] = self.damping_ratio[b, a] = ratio

        n = len(self.radius)
        self.force = np.zeros((n, 3))
        self.torque = np.zeros((n, 3))
        self.dissipative_force = np.zeros((n, 3))
        self.elastic = 0.0
        self.dissipated = 0.0
        self.kinetic = float(np.sum(0.5 * self.mass * np.einsum("ij,ij->i", self.velocity, self.velocity)))
        self.potential = float(np.sum(-self.mass * (self.position @ self.gravity)))
        self._check_no_overlap(scene_file)

    def __len__(self):
        return len(self.radius)

    def _check_no_overlap(self, scene_file):
        first, second, distance, reach = self._pairs()
        overlapping = distance < reach * (1 - 1e-6)
        if overlapping.any():
            k = int(np.argmax(overlapping))
            raise SceneError("{}: sphere {} at {} overlaps sphere {} at {} by {:g} m. Fix: move or shrink one".format(
                scene_file, first[k], self.position[first[k]].tolist(), second[k],
                self.position[second[k]].tolist(), reach[k] - distance[k]))

    def _pairs(self):
        first, second = np.triu_indices(len(self), k=1)
        distance = np.linalg.norm(self.position[second] - self.position[first], axis=1)
        return first, second, distance, self.radius[first] + self.radius[second]

    def pair_stiffness(self, a, b):
        """k_n of spheres a and b, N/m: the scene's normal_stiffness, or LS-DYNA's NormK
        scale * K_a r_a K_b r_b / (K_a r_a + K_b r_b)."""
        if self.normal_stiffness is not None:
            return np.full(np.shape(a), float(self.normal_stiffness))
        ka, kb = self.stiffness_term[a], self.stiffness_term[b]
        return self.stiffness_scale * ka * kb / (ka + kb)

    def stable_dt(self):
        """A fifth of the period of the stiffest spring on the lightest free sphere, s (paper eq. 7's
        DEM term); infinite when every sphere is fixed."""
        free = ~self.fixed
        if not free.any():
            return math.inf
        if self.normal_stiffness is not None:
            stiffest = float(self.normal_stiffness)
        else:
            terms = np.sort(self.stiffness_term)[::-1]
            largest, second = terms[0], terms[1] if len(terms) > 1 else terms[0]
            stiffest = self.stiffness_scale * largest * second / (largest + second)
        return 0.2 * math.pi * math.sqrt(float(self.mass[free].min()) / stiffest)

    def compute_internal_forces(self):
        """Gravity and the sphere-sphere springs at x_n (velocities v_{n-1/2}) into self.force."""
        self.force[:] = 0.0
        self.torque[:] = 0.0
        self.dissipative_force[:] = 0.0
        self.elastic = 0.0
        first, second, distance, reach = self._pairs()
        touching = distance < reach
        if touching.any():
            a, b = first[touching], second[touching]
            overlap = reach[touching] - distance[touching]
            normal = (self.position[b] - self.position[a]) / distance[touching][:, None]  # from a to b
            approach = np.einsum("ij,ij->i", self.velocity[b] - self.velocity[a], normal)  # < 0 closing
            stiffness = self.pair_stiffness(a, b)
            inverse_mass = np.where(self.fixed[a], 0.0, 1.0 / self.mass[a]) + np.where(
                self.fixed[b], 0.0, 1.0 / self.mass[b])
            effective_mass = np.where(inverse_mass > 0, 1.0 / np.maximum(inverse_mass, 1e-300), 0.0)
            damping = 2.0 * self.damping_ratio[self.material[a], self.material[b]] * np.sqrt(stiffness * effective_mass)
            magnitude = stiffness * overlap - damping * approach  # compression > 0
            on_b = magnitude[:, None] * normal
            dashpot_on_b = (-damping * approach)[:, None] * normal
            np.add.at(self.force, b, on_b)
            np.add.at(self.force, a, -on_b)
            np.add.at(self.dissipative_force, b, dashpot_on_b)
            np.add.at(self.dissipative_force, a, -dashpot_on_b)
            self.elastic = float(np.sum(0.5 * stiffness * overlap * overlap))
        free = ~self.fixed
        self.force[free] += self.mass[free, None] * self.gravity

    def add_coupling_forces(self, index, force, torque):
        """The coupler's contact forces (and torques) on the spheres listed in `index`, 3 values each."""
        index = np.asarray(index, dtype=np.int64)
        if len(index) and (index.min() < 0 or index.max() >= len(self)):
            raise ValueError("forces for sphere {} of {}".format(int(index.max()), len(self)))
        np.add.at(self.force, index, np.asarray(force, dtype=np.float64).reshape(-1, 3))
        if len(torque):
            np.add.at(self.torque, index, np.asarray(torque, dtype=np.float64).reshape(-1, 3))

    def integrate(self, dt_previous, dt):
        """Central differences: v_{n+1/2} = v_{n-1/2} + (dt_{n-1} + dt_n)/2 a_n (dt_0/2 on the first
        step), x_{n+1} = x_n + dt_n v_{n+1/2}. The energies are those at t_n."""
        first_step = dt_previous == 0
        dt_update = 0.5 * dt if first_step else 0.5 * (dt_previous + dt)
        free = ~self.fixed
        velocity = self.velocity.copy()
        spin = self.spin.copy()
        velocity[free] += (dt_update / self.mass[free])[:, None] * self.force[free]
        spin[free] += (dt_update / self.inertia[free])[:, None] * self.torque[free]
        if first_step:
            kinetic = 0.5 * self.mass * np.einsum("ij,ij->i", self.velocity, self.velocity)
            kinetic += 0.5 * self.inertia * np.einsum("ij,ij->i", self.spin, self.spin)
        else:  # the mean of the half-step kinetic energies: exact for a constant force
            kinetic = 0.5 * self.mass * np.einsum("ij,ij->i", self.velocity, velocity)
            kinetic += 0.5 * self.inertia * np.einsum("ij,ij->i", self.spin, spin)
        self.kinetic = float(np.sum(kinetic[free]))
        self.potential = float(np.sum(-self.mass[free] * (self.position[free] @ self.gravity)))
        power = -0.5 * np.einsum("ij,ij->i", self.dissipative_force, self.velocity + velocity)
        self.dissipated += dt_update * float(np.sum(power[free]))
        self.velocity, self.spin = velocity, spin
        self.position[free] += dt * velocity[free]
