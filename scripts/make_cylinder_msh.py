#!/usr/bin/python3
"""Writes a hexahedral mesh of a circular cylinder along z as a Gmsh msh 4.1 ASCII file, with the
physical groups a scene's constraints can name: "bar" (the volume), "impact" (the face z = base),
"top" (the face z = base + length) and "side" (the lateral surface).

    scripts/make_cylinder_msh.py OUT.msh --radius 3.2e-3 --length 32.4e-3 --section 8 --axial 30

The section is an n x n grid mapped onto the disc by the elliptical grid mapping
x = u sqrt(1 - v^2 / 2), y = v sqrt(1 - u^2 / 2), u, v in [-1, 1]: node for node (and bit for bit)
the mesh of fem_solver/mesh/hex_mesh.hpp `structured_cylinder`, so that a scene run and the
in-process F2 test (tests/fem_solver/test_solid_plastic.cpp) mesh the Taylor bar alike.
"""
import argparse
import math


def cylinder(radius, length, section, axial, base_z):
    nodes = []
    for k in range(axial + 1):
        for j in range(section + 1):
            for i in range(section + 1):
                # structured_box: min + size * i / n, then the disc mapping.
                u = -1.0 + 2.0 * i / section
                v = -1.0 + 2.0 * j / section
                z = 0.0 + length * k / axial
                x = u * math.sqrt(1.0 - 0.5 * v * v)
                y = v * math.sqrt(1.0 - 0.5 * u * u)
                nodes.append((radius * x, radius * y, base_z + z))

    def node(i, j, k):
        return 1 + i + (section + 1) * (j + (section + 1) * k)

    hexes = []
    for k in range(axial):
        for j in range(section):
            for i in range(section):
                hexes.append((node(i, j, k), node(i + 1, j, k), node(i + 1, j + 1, k), node(i, j + 1, k),
                              node(i, j, k + 1), node(i + 1, j, k + 1), node(i + 1, j + 1, k + 1),
                              node(i, j + 1, k + 1)))
    bottom = [(node(i, j, 0), node(i, j + 1, 0), node(i + 1, j + 1, 0), node(i + 1, j, 0))
              for j in range(section) for i in range(section)]
    top = [(node(i, j, axial), node(i + 1, j, axial), node(i + 1, j + 1, axial), node(i, j + 1, axial))
           for j in range(section) for i in range(section)]
    side = []
    for k in range(axial):
        for i in range(section):
            side.append((node(i, 0, k), node(i + 1, 0, k), node(i + 1, 0, k + 1), node(i, 0, k + 1)))
            side.append((node(i + 1, section, k), node(i, section, k), node(i, section, k + 1),
                         node(i + 1, section, k + 1)))
        for j in range(section):
            side.append((node(section, j, k), node(section, j + 1, k), node(section, j + 1, k + 1),
                         node(section, j, k + 1)))
            side.append((node(0, j + 1, k), node(0, j, k), node(0, j, k + 1), node(0, j + 1, k + 1)))
    return nodes, hexes, [bottom, top, side]


def write(path, nodes, hexes, surfaces):
    r = max(math.hypot(x, y) for x, y, _ in nodes)
    z0 = min(z for _, _, z in nodes)
    z1 = max(z for _, _, z in nodes)
    box = "{:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g}".format(-r, -r, z0, r, r, z1)
    lines = ["$MeshFormat", "4.1 0 8", "$EndMeshFormat", "$PhysicalNames", "4",
             '3 1 "bar"', '2 2 "impact"', '2 3 "top"', '2 4 "side"', "$EndPhysicalNames",
             "$Entities", "0 0 3 1",
             "1 {} 1 2 0".format(box), "2 {} 1 3 0".format(box), "3 {} 1 4 0".format(box),
             "1 {} 1 1 0".format(box), "$EndEntities",
             "$Nodes", "1 {0} 1 {0}".format(len(nodes)), "3 1 0 {}".format(len(nodes))]
    lines += [str(k + 1) for k in range(len(nodes))]
    lines += ["{:.17g} {:.17g} {:.17g}".format(*p) for p in nodes]
    lines.append("$EndNodes")
    count = len(hexes) + sum(len(s) for s in surfaces)
    lines += ["$Elements", "4 {0} 1 {0}".format(count)]
    tag = 1
    lines.append("3 1 5 {}".format(len(hexes)))
    for h in hexes:
        lines.append(" ".join(str(n) for n in (tag,) + h))
        tag += 1
    for entity, quads in enumerate(surfaces, start=1):
        lines.append("2 {} 3 {}".format(entity, len(quads)))
        for q in quads:
            lines.append(" ".join(str(n) for n in (tag,) + q))
            tag += 1
    lines.append("$EndElements")
    with open(path, "w") as handle:
        handle.write("\n".join(lines) + "\n")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out")
    parser.add_argument("--radius", type=float, default=3.2e-3, help="m")
    parser.add_argument("--length", type=float, default=32.4e-3, help="m")
    parser.add_argument("--section", type=int, default=8, help="elements across the section")
    parser.add_argument("--axial", type=int, default=30, help="elements along the axis")
    parser.add_argument("--base", type=float, default=0.0, help="z of the base face, m")
    args = parser.parse_args()
    write(args.out, *cylinder(args.radius, args.length, args.section, args.axial, args.base))


if __name__ == "__main__":
    main()
