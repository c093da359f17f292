#!/usr/bin/python3
"""A reference DEM solver in Python for the Sabo coupling protocol (docs/adding-a-solver.md).

    solver.py --scene SCENE --coupler ENDPOINT --out RUN_DIR

It takes the dem_solver's role: name it in a scene,

    [solvers.dem]
    command = ["/usr/bin/python3", "../../examples/python_dem/solver.py"]   # relative to the scene's folder

and `./sabo run SCENE` starts it in place of build/bin/dem_solver. Needs Debian's python3 (3.11, for
tomllib) with python3-numpy, python3-zmq and python3-protobuf, and the protobuf code the build
generates (sabo_wire.load_messages). The physics is dem_model.py; this file is the protocol side: it
registers, then answers every StepForces with the next StepState until the coupler says stop.
Exit status: 0 completed, 1 failed (an Error went to the coupler), 2 bad input, 130 stopped.
"""
import argparse
import os
import signal
import sys
import time
import tomllib

import numpy as np

import dem_model
import sabo_wire

NAME = "python_dem 1.0 (examples/python_dem)"
_stop_signal = []


def log(text):
    print("[python_dem] {}".format(text), file=sys.stderr, flush=True)


class Interest:
    """The boxes inside which spheres must be sent (StepForces.interest, interest_all)."""

    def __init__(self):
        self.all = False
        self.boxes = np.zeros((0, 6))

    def update(self, boxes, send_all):
        self.all = send_all
        self.boxes = np.array([[b.min_x, b.min_y, b.min_z, b.max_x, b.max_y, b.max_z] for b in boxes]).reshape(-1, 6)

    def select(self, position):
        """Indices of the positions inside any box (inclusive bounds), in increasing order."""
        if self.all:
            return np.arange(len(position))
        inside = np.zeros(len(position), dtype=bool)
        for box in self.boxes:
            inside |= np.all((position >= box[:3]) & (position <= box[3:]), axis=1)
        return np.nonzero(inside)[0]


class VtkSeries:
    """dem.pvd and dem/dem_<step>.vtp, the files ParaView opens (the same names as the dem_solver's)."""

    def __init__(self, run_dir):
        self.run_dir = run_dir
        self.entries = []
        os.makedirs(os.path.join(run_dir, "dem"), exist_ok=True)

    def write(self, step, time_s, model):
        name = "dem/dem_{:07d}.vtp".format(step)
        n = len(model)

        def array(label, values, components):
            text = " ".join(repr(float(v)) for v in np.asarray(values).ravel())
            return ('<DataArray type="Float64" Name="{}" NumberOfComponents="{}" format="ascii">{}</DataArray>'
                    .format(label, components, text))

        with open(os.path.join(self.run_dir, name), "w", encoding="utf-8") as handle:
            handle.write('<?xml version="1.0"?>\n<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian">'
                         '<PolyData><Piece NumberOfPoints="{}" NumberOfVerts="{}">'.format(n, n))
            handle.write("<Points>{}</Points>".format(array("Points", model.position, 3)))
            handle.write('<Verts><DataArray type="Int64" Name="connectivity" format="ascii">{}</DataArray>'
                         '<DataArray type="Int64" Name="offsets" format="ascii">{}</DataArray></Verts>'.format(
                             " ".join(str(i) for i in range(n)), " ".join(str(i + 1) for i in range(n))))
            handle.write("<PointData>{}{}{}</PointData>".format(
                array("radius", model.radius, 1), array("velocity", model.velocity, 3),
                array("angular_velocity", model.spin, 3)))
            handle.write("</Piece></PolyData></VTKFile>\n")
        self.entries.append((time_s, name))
        temporary = os.path.join(self.run_dir, "dem.pvd.tmp")
        with open(temporary, "w", encoding="utf-8") as handle:
            handle.write('<?xml version="1.0"?>\n<VTKFile type="Collection" version="1.0"><Collection>\n')
            for t, file in self.entries:
                handle.write('<DataSet timestep="{!r}" file="{}"/>\n'.format(t, file))
            handle.write("</Collection></VTKFile>\n")
        os.replace(temporary, os.path.join(self.run_dir, "dem.pvd"))  # never a half-written series


def describe(pb, model):
    registration = pb.Register(protocol_version=sabo_wire.PROTOCOL_VERSION, role=pb.ROLE_DEM, name=NAME,
                               pid=os.getpid(), exposes_particles=True, exposes_angular_velocity=True,
                               stable_dt=model.stable_dt(), checkpoints=False)
    table = registration.particles
    table.id.extend(range(len(model)))
    table.radius.extend(model.radius.tolist())
    table.mass.extend(model.mass.tolist())
    table.material.extend(model.material.tolist())
    table.body.extend(model.body.tolist())
    return registration


def fill_state(pb, state, model, interest):
    chosen = interest.select(model.position)
    state.index.extend(chosen.tolist())
    state.position.extend(model.position[chosen].ravel().tolist())
    state.velocity.extend(model.velocity[chosen].ravel().tolist())
    state.angular_velocity.extend(model.spin[chosen].ravel().tolist())
    state.energies.CopyFrom(pb.Energies(kinetic=model.kinetic, potential=model.potential, elastic=model.elastic,
                                        dissipated=model.dissipated))


def run(link, model, output):
    """The step loop of docs/protocol.md, "Life of a solver". Returns the steps done."""
    pb = link.pb
    reply = link.register(describe(pb, model))
    log("registered with the coupler at {}; {} spheres, end time {:g} s".format(
        link.endpoint, len(model), reply.end_time))
    interest = Interest()
    interest.update(reply.interest, reply.interest_all)
    step, time_s, dt_previous = 0, 0.0, 0.0
    since_last, total = 0.0, 0.0  # compute seconds since the previous state, and in all
    while True:
        start = time.monotonic()
        state = pb.StepState(step=step, time=time_s, stable_dt=model.stable_dt())
        fill_state(pb, state, model, interest)
        since_last += time.monotonic() - start
        state.compute_seconds = since_last
        state.wait_seconds = link.wait_seconds
        link.send(state)
        start = time.monotonic()
        model.compute_internal_forces()  # while the coupler computes the contacts
        overlapped = time.monotonic() - start
        forces = link.receive_forces(step)
        start = time.monotonic()
        model.add_coupling_forces(forces.index, forces.force, forces.torque)
        interest.update(forces.interest, forces.interest_all)
        if forces.output:
            output.write(step, time_s, model)
        if forces.stop:
            return step + 1, total + overlapped + time.monotonic() - start
        model.integrate(dt_previous, forces.dt)
        time_s += forces.dt
        dt_previous = forces.dt
        step += 1
        since_last = overlapped + time.monotonic() - start
        total += since_last


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", required=True, help="scene file (TOML)")
    parser.add_argument("--coupler", required=True, help="coupler endpoint, e.g. ipc:///tmp/run/coupler.sock")
    parser.add_argument("--out", default=".", help="run folder for output files")
    parser.add_argument("--resume", help="not supported: this solver writes no checkpoints")
    parser.add_argument("--keys", help="the run's key set (RUN_DIR/keys): CURVE keys over tcp, the token over ipc")
    args = parser.parse_args(argv)
    if args.resume:
        log("--resume {}: this solver cannot restart from a checkpoint (it registers checkpoints = false). "
            "Fix: start it without --resume".format(args.resume))
        return 2
    try:
        with open(args.scene, "rb") as handle:
            scene = tomllib.load(handle)
        model = dem_model.DemModel(scene, args.scene)
        messages = sabo_wire.load_messages()
    except (dem_model.SceneError, sabo_wire.ProtocolError) as error:  # their messages name the file
        log(str(error))
        return 2
    except (OSError, tomllib.TOMLDecodeError, KeyError) as error:
        log("{}: {}".format(args.scene, error if not isinstance(error, KeyError) else "missing key {}".format(error)))
        return 2
    if model.ignored:
        log("[contact.dem_dem] {}: ignored (normal springs only between spheres)".format(", ".join(model.ignored)))

    signal.signal(signal.SIGTERM, lambda number, frame: _stop_signal.append(number))
    signal.signal(signal.SIGINT, lambda number, frame: _stop_signal.append(number))
    hang_timeout = float(scene.get("run", {}).get("hang_timeout", 10.0))
    # A scene that runs tcp in clear (tcp_security = "none") has a coupler that takes no keys.
    in_clear = args.coupler.startswith("tcp://") and scene.get("run", {}).get("tcp_security") == "none"
    try:
        link = sabo_wire.SolverLink(messages, args.coupler, max(60.0, 6.0 * hang_timeout), lambda: bool(_stop_signal),
                                    keys=None if in_clear else args.keys)
    except sabo_wire.ProtocolError as error:
        log(str(error))
        return 2
    goodbye = messages.Goodbye(reason="completed")
    code, steps, compute = 0, 0, 0.0
    try:
        steps, compute = run(link, model, VtkSeries(args.out))
        log("completed {} steps".format(steps))
    except sabo_wire.StopRequested as stop:
        log(str(stop))
        goodbye.reason, code = str(stop), 130
    except Exception as error:  # any failure goes to the coupler before the exit, as the protocol asks
        log("failed: {}: {}".format(type(error).__name__, error))
        link.send_error("dem_solver (python): {}".format(error))
        code = 1
    if code != 1:
        goodbye.steps, goodbye.compute_seconds, goodbye.wait_seconds = steps, compute, link.wait_seconds
        link.send(goodbye)
    link.close()
    return code


if __name__ == "__main__":
    sys.exit(main())
