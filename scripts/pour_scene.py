#!/usr/bin/env python3
"""Write examples/pour64.toml: 64 objects of eight kinds (boxes, balls, two closed meshes and
four synthetic splat toys) in 8 layers of 4 x 2 above the open-top container of
examples/container.toml, poured in by gravity.

    python3 scripts/pour_scene.py > examples/pour64.toml
"""

KINDS = [
    # (name, shape, offset from the grid point to the shape's placement origin, material)
    ("box", "box:0.1,0.1,0.1", (-0.05, -0.05, -0.05), (2e5, 0.4, 500.0)),
    ("ball", "sphere:0.05", (0.0, 0.0, 0.0), (1e5, 0.45, 400.0)),
    ("block", "data/splats/block.ply", (0.0, 0.0, 0.0), (2e5, 0.4, 500.0)),
    ("egg", "data/splats/egg.ply", (0.0, 0.0, 0.0), (1e5, 0.45, 400.0)),
    ("torus", "data/torus.obj", (0.0, 0.0, 0.0), (1e5, 0.45, 300.0)),
    ("dog", "data/splats/dog.ply", (0.0, 0.0, 0.0), (1e5, 0.45, 400.0)),
    ("ell", "data/ell.obj", (0.0, 0.0, 0.0), (2e5, 0.4, 500.0)),
    ("slab", "data/splats/slab.ply", (0.0, 0.0, 0.0), (2e5, 0.4, 500.0)),
]

print("""# 64 objects of eight kinds poured into an open-top container (0.9 x 0.5 x 0.5 m, the
# one-sided mesh collider of examples/container.toml): boxes, balls, tori and L-prisms (closed
# meshes) and four synthetic Gaussian-splat toys (examples/data/splats: blocks, eggs, dog toys
# and slabs, whose contact samples lie on the surface derived from their splat centres).
# They start in 8 layers of 4 x 2, 0.17 m apart; 120 steps of 10 ms. Written by
# scripts/pour_scene.py; docs/performance.md has its measurements (slow: islands of up to
# 64 objects take tens of seconds a step on 2 cores).
#   cargo run --release -- run examples/pour64.toml --out out/pour64 --json > pour64.json
#   cargo run --release -- render out/pour64 --elevation 40

[simulation]
dt = 0.01
steps = 120
gravity = [0.0, -9.81, 0.0]

[solver]
hessian = "newton"
cubature = 400

[output]
every = 10

[contact]
friction = 0.4

[[collider]]
name = "container"
shape = { mesh = { file = "data/container.obj", sided = "outside" } }
""")
n = 0
for layer in range(8):
    for ix in range(4):
        for iz in range(2):
            name, shape, off, (e, nu, rho) = KINDS[(n + layer) % len(KINDS)]
            x = -0.315 + 0.21 * ix
            y = 0.09 + 0.17 * layer
            z = -0.11 + 0.22 * iz
            t = (x + off[0], y + off[1], z + off[2])
            print(f"""[[object]]
name = "{name}{n:02d}"
shape = "{shape}"
material = {{ youngs = {e:g}, poisson = {nu}, density = {rho} }}
basis = {{ kernels = 200, modes = 10 }}
placement = {{ translation = [{t[0]:.3f}, {t[1]:.3f}, {t[2]:.3f}] }}
""")
            n += 1
