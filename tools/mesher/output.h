// SPDX-License-Identifier: GPL-3.0-or-later
// After meshing: the last slivers on the outer boundary, quality figures,
// and the Gmsh file (output.cpp). No CGAL here.
#ifndef FTM_MESHER_OUTPUT_H
#define FTM_MESHER_OUTPUT_H

#include "mesher.h"

#include <string>
#include <vector>

namespace ftm_mesher {

// Removes tetrahedra below min_angle that have a face on the outer
// boundary (in no other tetrahedron): flat slivers lying on the surface,
// whose loss takes next to no volume and which no optimisation could move
// (their corners are all on the surface). Repeats while it finds some, then
// drops the nodes no tetrahedron uses. Returns how many it removed.
size_t remove_surface_slivers(Tet_mesh &m, double min_angle);

struct Quality {
    double min_angle = 180;        // smallest dihedral angle [degrees]
    size_t below = 0;              // tetrahedra with an angle below the bound
    double mean_edge = 0;          // over the tetrahedra's edges, in the mesh's units
    std::vector<size_t> per_tissue; // tetrahedra per tissue, index 0 unused
    double volume = 0;
};

Quality quality(const Tet_mesh &m, int tissue_count, double bound);

// Writes Gmsh MSH 4.1 ASCII: one volume entity and one physical group per
// tissue (tag = its index, named), the nodes in one block, each tissue's
// tetrahedra in one block. Coordinates with 17 digits: they read back
// exactly. False with *why when the file cannot be written.
bool write_gmsh(const std::string &path, const Tet_mesh &m, const std::vector<std::string> &names,
                std::string *why);

} // namespace ftm_mesher

#endif
