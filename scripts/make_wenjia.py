#!/usr/bin/env python3
"""Writes the Wenjia gully scenes (docs/wenjia.md) from one set of stated assumptions:

    configs/wenjia/profile_original.csv, configs/wenjia/profile_treated.csv   the bed of Branch 2
    configs/wenjia_original.toml, configs/wenjia_treated.toml                  the paper's resolution
    configs/tests/wenjia_original_reduced.toml, ..._treated_reduced.toml        coarse and short, for ctest

    scripts/make_wenjia.py [--check]    (--check: exit 1 when a written file would change)

Standard library only. The real profile of Branch 2 is not public: the one drawn here passes through the
elevations the paper gives (docs/wenjia.md says which, and what is assumed)."""
import argparse
import math
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

WIDTH = 7.0                  # m, the paper's strip
WALL_HEIGHT = 60.0           # m, the side walls above the bed: the source lies 40 m deep
BED_FRICTION = 0.1           # the slurry on the bed (Coulomb): see the scenes' [[interactions]]
CHANNEL_ELEMENT = 8.0        # m: the walls are flat and rigid; every profile point is a row of nodes

# The source (Deposition Area II, "the 1300 m platform and downstream"): a layer LAYER_DEPTH m deep (vertically)
# lying on the upper gully at UPPER_GRADIENT, its surface at PLATFORM at the back, ending in a face at 37
# degrees (0.75); as long as it takes to hold the paper's 40 712 particles at its 2 m spacing (the same mass).
# Released from rest, as in the paper. A column standing 148 m deep (the paper's "up to 150 m") collapsed
# like a dam break with twice the paper's front speeds (docs/wenjia.md).
PLATFORM = 1300.0
LAYER_DEPTH = 40.0
UPPER_GRADIENT = 0.125
FACE_GRADIENT = 0.75
PAPER_PARTICLES, PAPER_SPACING = 40712, 2.0
FACE_RUN = LAYER_DEPTH / (FACE_GRADIENT - UPPER_GRADIENT)  # horizontal run of the face
BED_START = (0.0, PLATFORM - LAYER_DEPTH)


def inset(polygon, distance):
    """The counterclockwise convex polygon with every edge moved `distance` inward (its corners where the moved
    edges meet): the particles' lattice then keeps half a spacing off the bed, the back wall and the face."""
    lines = []
    for (x0, z0), (x1, z1) in zip(polygon, polygon[1:] + polygon[:1]):
        length = math.hypot(x1 - x0, z1 - z0)
        nx, nz = -(z1 - z0) / length, (x1 - x0) / length  # inward (left of the edge) for a counterclockwise polygon
        lines.append(((x0 + distance * nx, z0 + distance * nz), (x1 - x0, z1 - z0)))
    corners = []
    for k in range(len(lines)):
        (px, pz), (dx, dz) = lines[k - 1]
        (qx, qz), (ex, ez) = lines[k]
        t = ((qx - px) * ez - (qz - pz) * ex) / (dx * ez - dz * ex)
        corners.append((px + t * dx, pz + t * dz))
    return corners


def layer_polygon(face_top):
    """The deposit's outline (s, z) counterclockwise, its surface ending at s = face_top: along the bed, up the
    face, back along the surface."""
    toe = face_top + FACE_RUN
    return [BED_START, (toe, BED_START[1] - UPPER_GRADIENT * toe), (face_top, PLATFORM - UPPER_GRADIENT * face_top),
            (0.0, PLATFORM)]


def lattice_count(extent, dx):
    """Layers of spacing dx in `extent`, as the sph_solver counts them (to a relative 1e-6)."""
    return int(math.floor(extent / dx * (1 + 1e-6)))


def particle_count(polygon, dx):
    """The particles the sph_solver puts in the strip: cell centres of a dx lattice from the corner of the
    outline inset by dx/2 (written to the scene), inside it, times the rows across WIDTH."""
    outline = inset(polygon, dx / 2)
    s_min, z_min = min(s for s, _ in outline), min(z for _, z in outline)
    z_max = max(z for _, z in outline)
    count = 0
    for k in range(lattice_count(z_max - z_min, dx)):
        z = z_min + (k + 0.5) * dx
        crossings = sorted(s0 + (z - z0) * (s1 - s0) / (z1 - z0) for (s0, z0), (s1, z1) in
                           zip(outline, outline[1:] + outline[:1]) if (z0 <= z) != (z1 <= z))
        for left, right in zip(crossings[::2], crossings[1::2]):
            first = math.ceil((left - s_min) / dx - 0.5)
            last = math.floor((right - s_min) / dx - 0.5)
            count += max(0, last - first + 1)
    return count * lattice_count(WIDTH, dx)


def paper_face_top():
    """The shortest surface (to 0.1 m) at which the layer holds the paper's particles at its spacing."""
    low, high = 10.0, 5000.0
    for _ in range(40):
        middle = 0.5 * (low + high)
        if particle_count(layer_polygon(middle), PAPER_SPACING) < PAPER_PARTICLES:
            low = middle
        else:
            high = middle
    # The lattice moves with the toe, so the count is not quite monotonic: from there up in steps of 0.1 m.
    face_top = math.floor(low * 10) / 10
    while particle_count(layer_polygon(face_top), PAPER_SPACING) < PAPER_PARTICLES:
        face_top = round(face_top + 0.1, 1)
    return face_top


# The bed, (horizontal distance, elevation) in m, before the structures' seats: the upper gully under the
# source at UPPER_GRADIENT to the source's toe, the gully at 1:5 from there to the mouth (950 m), the fan at
# 6:100 to the Mianyuan river.
FACE_TOP = paper_face_top()
SOURCE_REACH_END = layer_polygon(FACE_TOP)[1]  # the source's toe
# The boulders: the 200 m of the deposit behind its face (a debris flow carries its boulders in its front).
BOULDERS_FROM, BOULDERS_TO = FACE_TOP - 220.0, FACE_TOP - 20.0
GULLY_GRADIENT = 0.2
MOUTH_ELEVATION = 950.0
FAN_GRADIENT = 0.06
FAN_LENGTH = 790.0

# Structures, by elevation of the bed as the paper places them.
SILL_TOP, SILL_BOTTOM, SILL_SPACING, SILL_HEIGHT, SILL_THICKNESS = 1075.0, 985.0, 20.0, 2.0, 2.0
CHECK_DAM_ELEVATION, CHECK_DAM_HEIGHT, CHECK_DAM_THICKNESS = 980.0, 8.0, 2.0
STEPS_TOP, STEPS_BOTTOM, STEP_COUNT, STEP_RISER = 1035.0, 980.0, 9, 1.0  # riser: horizontal run of a 6 m drop
SLIT_DAM_ELEVATIONS, SLIT_DAM_HEIGHT, SLIT_DAM_THICKNESS = (979.0, 965.0, 951.0), 10.0, 3.0
SLIT_WIDTH = 1.5             # m, one slit through each dam to the ground (assumed: the paper gives no number)
HOUSES_AFTER_CHECK_DAM, HOUSE_SPACING, HOUSE_LENGTH, HOUSE_WIDTH = 300.0, 20.0, 4.0, 6.0
# Dams and sills span the gully and are keyed into its banks: held on their base and on both sides (the strip's
# side walls). The houses stand on the fan, held on their base only.
KEYED_INTO_BANKS = ("z-", "y-", "y+")
FLOOR_HEIGHT, FLOORS = 3.6, 3


def gully_s(elevation):
    """Distance at which the 1:5 gully reaches `elevation`."""
    return SOURCE_REACH_END[0] + (SOURCE_REACH_END[1] - elevation) / GULLY_GRADIENT


MOUTH_S = gully_s(MOUTH_ELEVATION)
PROFILE_END = MOUTH_S + FAN_LENGTH


def bed(s):
    """The bed's elevation at distance s without the step pools."""
    if s <= SOURCE_REACH_END[0]:
        return BED_START[1] + (SOURCE_REACH_END[1] - BED_START[1]) * s / SOURCE_REACH_END[0]
    if s <= MOUTH_S:
        return SOURCE_REACH_END[1] - GULLY_GRADIENT * (s - SOURCE_REACH_END[0])
    return MOUTH_ELEVATION - FAN_GRADIENT * (s - MOUTH_S)


def step_pools():
    """The treated bed between STEPS_TOP and STEPS_BOTTOM: STEP_COUNT drops of (top - bottom) / count m, each
    over STEP_RISER m, between flat pools."""
    start, end = gully_s(STEPS_TOP), gully_s(STEPS_BOTTOM)
    drop = (STEPS_TOP - STEPS_BOTTOM) / STEP_COUNT
    tread = (end - start) / STEP_COUNT - STEP_RISER
    points, s, z = [], start, STEPS_TOP
    for _ in range(STEP_COUNT):
        points.append((s, z))
        s += tread
        points.append((s, z))
        s += STEP_RISER
        z -= drop
    points.append((end, STEPS_BOTTOM))
    return points


def profile(treated):
    corners = [BED_START, SOURCE_REACH_END, (MOUTH_S, MOUTH_ELEVATION), (PROFILE_END, bed(PROFILE_END))]
    if treated:
        pools = step_pools()
        corners = [p for p in corners if not pools[0][0] <= p[0] <= pools[-1][0]] + pools
    return sorted(corners)


def profile_elevation(points, s):
    for (s0, z0), (s1, z1) in zip(points, points[1:]):
        if s0 <= s <= s1:
            return z0 + (z1 - z0) * (s - s0) / (s1 - s0)
    raise ValueError("distance {} outside the profile".format(s))


def source_polygon():
    """The deposit's outline (s, z) counterclockwise: along the bed, up the face, back along the surface."""
    return layer_polygon(FACE_TOP)


def polygon_area(points):
    return 0.5 * abs(sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(points, points[1:] + points[:1])))


def number(value):
    text = "{:.6g}".format(value)
    return text if any(c in text for c in ".e") else text + ".0"


def vec(values):
    return "[" + ", ".join(number(v) for v in values) + "]"


class Scene:
    """The TOML text of one scene, section by section."""

    def __init__(self):
        self.parts = []

    def add(self, text):
        self.parts.append(text.strip("\n") + "\n")

    def text(self):
        return "\n".join(self.parts)


def box_on_bed(name, points, s_upstream, length, height, material, extra, across=WIDTH, fixed=("z-",)):
    """A deformable box from s_upstream, `length` along the flow, `across` wide about the centre line, standing
    on the bed at its downstream face (its upstream part sits in the bed, which is rigid and does not touch
    it), its faces `fixed` held."""
    base = profile_elevation(points, s_upstream + length)
    half = 0.5 * across
    return """
[[structures]]
name = "{name}"
material = "{material}"
rigid = false
shape = "box"
min = {lo}
max = {hi}
fixed = [{fixed}]
{extra}""".format(name=name, material=material, lo=vec((s_upstream, -half, base)),
                   hi=vec((s_upstream + length, half, base + height)), extra=extra.strip("\n"),
                   fixed=", ".join('"{}"'.format(face) for face in fixed))


def channel_part(name, profile_file):
    """The keys a rigid channel part along the profile file starts with."""
    return """[[structures]]
name = "{name}"
material = "concrete"
shape = "channel"
origin = [0.0, 0.0, 0.0]
direction = [1.0, 0.0, 0.0]
profile_file = "{profile}"
width = {width}""".format(name=name, profile=profile_file, width=number(WIDTH))


def scene_text(layout, reduced):
    treated = layout == "treated"
    points = profile(treated)
    dx = 3.5 if reduced else 2.0
    end_time = 1.0 if reduced else (160.0 if treated else 120.0)
    boulders = 30 if reduced else 213
    sound_speed = 400.0
    check_dam_s = gully_s(CHECK_DAM_ELEVATION)
    houses_s = [check_dam_s + HOUSES_AFTER_CHECK_DAM + k * (HOUSE_LENGTH + HOUSE_SPACING) for k in range(3)]
    lowest = min(z for _, z in points)
    s = Scene()
    what = ("step pools and three slit dams (the treated layout)" if treated
            else "the last check dam and the ground sills (the original layout)")
    s.add("""
# The Wenjia gully debris flow of 13 August 2010{reduced}, {what}: written by scripts/make_wenjia.py, which
# holds the assumptions (docs/wenjia.md). The paper's pseudo-3-D strip: the longitudinal profile of Branch 2
# (configs/wenjia/profile_{layout}.csv, assumed: the real one is not public) extruded {width} m wide between
# rigid side walls; a Bingham slurry with the field's yield stress and viscosity released from rest below the
# 1300 m platform, {boulders} granite boulders of 1-2 m in it, deformable masonry structures that erode, brick
# houses with concrete roof slabs. x runs down the gully (horizontal distance), z is the elevation in m.
format_version = 1
""".format(reduced=" (reduced: coarse and short, for ctest)" if reduced else "", what=what, layout=layout,
           width=number(WIDTH), boulders=boulders))
    s.add("""
[run]
end_time = {end}
output_interval = {output}
gravity = [0.0, 0.0, -9.8]   # the paper's
multirate = true             # the structures' elements step faster than the slurry: they substep
""".format(end=number(end_time), output=number(0.25 if reduced else 1.0)))
    s.add("""
[solvers.dem]
beta = 0.5

[solvers.fem]
beta = 0.9
""")
    s.add("""
[materials.slurry]         # the field's rheology (Zhang et al. 2013), the paper's density
density = 2000.0
youngs_modulus = 1e9       # not used by the SPH solver
poisson_ratio = 0.0
rheology = "bingham"
viscosity = 136.0          # Pa s
yield_stress = 10029.0     # Pa
yield_shear_rate = 1.0     # 1/s: Papanastasiou regularisation

[materials.granite]        # the paper's boulders
density = 3000.0
youngs_modulus = 30e9
poisson_ratio = 0.3

[materials.concrete]       # the paper's channel
density = 3000.0
youngs_modulus = 30e9
poisson_ratio = 0.24

[materials.masonry]        # the paper's dams and sills (MAT_PLASTIC_KINEMATIC)
density = 2300.0
youngs_modulus = 8e9
poisson_ratio = 0.23
yield_stress = 8e6
failure_strain = 0.0033

[materials.brick]          # the paper's house walls
density = 2300.0
youngs_modulus = 8e9
poisson_ratio = 0.23
yield_stress = 8e6
failure_strain = 0.0033

[materials.slab]           # the paper's roof slabs
density = 2400.0
youngs_modulus = 28e9
poisson_ratio = 0.2
yield_stress = 16.7e6
failure_strain = 0.05
""")
    s.add("""
[sph]
particle_spacing = {dx}
smoothing_ratio = 1.5
sound_speed = {c}          # ten times the fastest flow the paper reports (34 m/s), rounded up
wall_model = "penalty"     # the dams erode: their new faces join the penalty contact
artificial_viscosity = 0.05
domain_min = {lo}
domain_max = {hi}
""".format(dx=number(dx), c=number(sound_speed), lo=vec((-10.0, -0.5 * WIDTH - 1.0, lowest - 10.0)),
           hi=vec((PROFILE_END + 10.0, 0.5 * WIDTH + 1.0, PLATFORM + 20.0))))
    polygon = source_polygon()
    s.add("""
# The deposit below the 1300 m platform: {area:.0f} m2 of profile, {volume:.3g} m3 in the strip.
[[fluids]]
name = "slurry"
material = "slurry"
shape = "extruded_polygon"
origin = [0.0, 0.0, 0.0]
direction = [1.0, 0.0, 0.0]
width = {width}
profile = [{polygon}]
""".format(area=polygon_area(polygon), volume=polygon_area(polygon) * WIDTH, width=number(WIDTH),
           polygon=", ".join(vec(corner) for corner in inset(polygon, dx / 2))))
    s.add("""
# The boulders (0.5 % of the flow): behind the deposit's face, in a box that fits inside the sloping layer.
[[particles]]
name = "boulders"
material = "granite"
fill = {{ min = {lo}, max = {hi}, count = {count}, diameter = [1.0, 2.0], seed = 2010 }}
""".format(lo=vec((BOULDERS_FROM, -0.5 * WIDTH + 1.1, bed(BOULDERS_FROM) + 1.5)),
           hi=vec((BOULDERS_TO, 0.5 * WIDTH - 1.1, PLATFORM - UPPER_GRADIENT * BOULDERS_TO - 1.5)), count=boulders))
    profile_file = ("../" if reduced else "") + "wenjia/profile_{}.csv".format(layout)
    s.add("""
# The channel: its bed with the wall behind the source, and its side walls as a part of their own, smooth
# (the strip stands for a 2-D profile: its walls are planes of symmetry, not the gully's banks).
{bed}
start_wall_height = {start_wall}
element_size = {element}   # m (the paper's: 2 m); flat rigid walls need no finer

{walls}
floor = false
wall_height = {wall}
element_size = {element}
""".format(bed=channel_part("gully", profile_file), walls=channel_part("gully_walls", profile_file),
           element=number(CHANNEL_ELEMENT), wall=number(WALL_HEIGHT),
           start_wall=number(PLATFORM + 20.0 - BED_START[1])))
    if treated:
        for k, elevation in enumerate(SLIT_DAM_ELEVATIONS):
            s.add(box_on_bed("slit_dam_{}".format(k + 1), points, gully_s(elevation), SLIT_DAM_THICKNESS,
                             SLIT_DAM_HEIGHT, "masonry", """
slit_count = 1
slit_width = {w}
slit_depth = {d}
slit_axis = "x"
element_size = 1.0""".format(w=number(SLIT_WIDTH), d=number(SLIT_DAM_HEIGHT)), fixed=KEYED_INTO_BANKS))
    else:
        s.add(box_on_bed("check_dam", points, check_dam_s - CHECK_DAM_THICKNESS, CHECK_DAM_THICKNESS,
                         CHECK_DAM_HEIGHT, "masonry", "element_size = 1.0", fixed=KEYED_INTO_BANKS))
        sill = gully_s(SILL_TOP)
        k = 0
        while bed(sill) >= SILL_BOTTOM - 1e-9:
            k += 1
            s.add(box_on_bed("sill_{:02d}".format(k), points, sill, SILL_THICKNESS, SILL_HEIGHT, "masonry",
                             "element_size = 1.0", fixed=KEYED_INTO_BANKS))
            sill += SILL_SPACING
    for k, house_s in enumerate(houses_s):
        s.add(box_on_bed("house_{}".format(k + 1), points, house_s, HOUSE_LENGTH, FLOORS * FLOOR_HEIGHT, "brick", """
thickness = 0.24
floors = {floors}
roof_thickness = 0.1
roof_material = "slab"
element_size = 1.8                   # half a storey""".format(floors=FLOORS), across=HOUSE_WIDTH))
    stations = [("source_toe", source_polygon()[1][0]), ("mouth", MOUTH_S)]
    if treated:
        stations += [("step_pools_top", gully_s(STEPS_TOP))] + [
            ("slit_dam_{}".format(k + 1), gully_s(e) - 1.0) for k, e in enumerate(SLIT_DAM_ELEVATIONS)]
    else:
        stations += [("first_sill", gully_s(SILL_TOP) - 1.0), ("check_dam", check_dam_s - CHECK_DAM_THICKNESS - 1.0)]
    stations += [("house_{}".format(k + 1), h - 1.0) for k, h in enumerate(houses_s)]
    stations.sort(key=lambda item: item[1])
    s.add("""
# The front along the gully and the deposit at the stations (fronts.csv, front_stations.csv, summary.json).
[[fronts]]
name = "debris_front"
kind = "channel"
channel = "gully"
ahead = 8                  # a few particles thrown ahead of the flow do not make its front
interval = {interval}
stations = [
{stations}
]
""".format(interval=number(0.25 if reduced else 1.0), stations=",\n".join(
        "  {{ name = \"{}\", at = {} }}".format(name, number(at)) for name, at in stations)))
    s.add("""
[contact.dem_dem]          # the paper's boulder contact
normal_damping_ratio = 0.7
tangential_damping_ratio = 0.4
friction = 1.0
rolling_friction = 0.1
normal_stiffness_scale = 0.01

[contact.dem_fem]
friction = 0.4
normal_stiffness = 1e8     # N/m: a contact step of 0.2 pi sqrt(m / k) = 2.5 ms for the lightest boulder
normal_damping_ratio = 0.2

[contact.sph_fem]
friction = 0.3
normal_stiffness = 1e9     # N/m: the slurry's particles ({mass:.3g} kg): a contact step above the SPH step

[contact.sph_dem]          # the paper's node-to-node penalty (eqs. 1-2): boulders of 1-2 m span less than the
model = "penalty"          # two spacings that boundary particles need
normal_stiffness = 2e7     # N/m: a pair step of 0.2 pi sqrt(m / k) = 5.6 ms for the lightest boulder
normal_damping_ratio = 0.2
friction = 0.3

[[interactions]]
pair = ["boulders", "gully"]
friction = 0.3

# The slurry's basal resistance: its Bingham yield stress inside, and Coulomb friction of 0.1 (5.7 degrees) on
# the bed, below the gully's 1:5 (11.3 degrees) and above the fan's 6:100 (3.4 degrees), where it deposits.
[[interactions]]
pair = ["slurry", "gully"]
friction = {bed_friction}

[[interactions]]
pair = ["slurry", "gully_walls"]
friction = 0.0

[[interactions]]
pair = ["boulders", "gully_walls"]
friction = 0.0

[recording]
fields = ["energies"]
every = 100
""".format(mass=2000.0 * dx ** 3, bed_friction=number(BED_FRICTION)))
    return s.text()


def profile_csv(layout):
    lines = ["# The bed of the Wenjia gully's Branch 2 as assumed by scripts/make_wenjia.py (docs/wenjia.md),",
             "# {} layout: horizontal distance from the back of the source and elevation, m.".format(layout),
             "distance,elevation"]
    lines += ["{},{}".format(number(s), number(z)) for s, z in profile(layout == "treated")]
    return "\n".join(lines) + "\n"


def outputs():
    files = {}
    for layout in ("original", "treated"):
        files["configs/wenjia/profile_{}.csv".format(layout)] = profile_csv(layout)
        files["configs/wenjia_{}.toml".format(layout)] = scene_text(layout, reduced=False)
        files["configs/tests/wenjia_{}_reduced.toml".format(layout)] = scene_text(layout, reduced=True)
    return files


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 when a file would change")
    args = parser.parse_args()
    changed = []
    for relative, text in outputs().items():
        path = os.path.join(ROOT, relative)
        old = None
        if os.path.exists(path):
            with open(path) as handle:
                old = handle.read()
        if old == text:
            continue
        changed.append(relative)
        if not args.check:
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "w") as handle:
                handle.write(text)
    polygon = source_polygon()
    print("source: {:.0f} m2 of profile, {:.3g} m3 in the {} m strip; mouth at s = {:.1f} m".format(
        polygon_area(polygon), polygon_area(polygon) * WIDTH, number(WIDTH), MOUTH_S))
    for relative in changed:
        print(("would change: " if args.check else "wrote ") + relative)
    return 1 if args.check and changed else 0


if __name__ == "__main__":
    sys.exit(main())
