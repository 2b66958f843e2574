#!/usr/bin/env python3
# usage: scripts/decimate_off.py IN.off OUT.off MAX_FACES   (docs/evaluation.md)
# Reduce a closed triangle surface to at most MAX_FACES faces by MeshLab's quadric edge
# collapse (pymeshlab), keeping its topology (no holes, no genus change) and never flipping
# a face; writes OUT.off (plain OFF) and prints "faces_in faces_out". The evaluation's FEM
# reference keeps every surface triangle (TetGen -Y), so a large input costs hours of FEM;
# this makes it affordable, as the paper's TetWild remeshing does. Whether the result is
# still a valid solid (closed, manifold, no self-intersection) is checked by the caller
# (scripts/cgal_shapes.sh), like any input.
import sys

import pymeshlab

src, dst, max_faces = sys.argv[1], sys.argv[2], int(sys.argv[3])
ms = pymeshlab.MeshSet()
ms.load_new_mesh(src)
# CGAL's files can repeat a vertex; collapse needs them shared to keep the surface closed.
ms.meshing_remove_duplicate_vertices()
before = ms.current_mesh().face_number()
if before > max_faces:
    ms.meshing_decimation_quadric_edge_collapse(
        targetfacenum=max_faces,
        preserveboundary=True,
        preservenormal=True,
        preservetopology=True,
        optimalplacement=True,
        planarquadric=True,
        qualitythr=0.3,
    )
    ms.meshing_remove_unreferenced_vertices()
after = ms.current_mesh().face_number()
ms.save_current_mesh(dst, save_vertex_color=False, save_face_color=False)
print(before, after)
