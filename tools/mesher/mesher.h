// SPDX-License-Identifier: GPL-3.0-or-later
// ftm-mesh: tissue meshes from segmented scans and closed surfaces
// (docs/meshes.md, "From a scan to a tissue mesh"). C++ because CGAL is;
// libftm stays C and is used through its C headers.
#ifndef FTM_MESHER_H
#define FTM_MESHER_H

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace ftm_mesher {

// A tetrahedral mesh: nodes (3 doubles each), tetrahedra (4 node indices,
// positive volume) and each one's tissue (1 .. number of tissues).
struct Tet_mesh {
    std::vector<double> xyz;
    std::vector<int32_t> tets;
    std::vector<int32_t> tissue;
    size_t tet_count() const { return tissue.size(); }
};

// How fine and how good: lengths in the frame of the input (mm for images).
struct Criteria {
    double size = 0;           // the largest elements' edge
    double facet_distance = 0; // surface triangles' distance from the true surface
    double min_angle = 10;     // the smallest dihedral angle aimed at [degrees]
};

// Progress lines ("what happened, how long it took"), to stderr.
using Progress = std::function<void(const std::string &)>;

// Smallest dihedral angle of a tetrahedron [degrees].
double min_dihedral(const double *a, const double *b, const double *c, const double *d);

// A labelled image meshed (mesh_image.cpp): tissue index per voxel (0 =
// outside), voxel size in mm, optional weights (0 .. 255 per voxel, the
// smoothed boundary: CGAL's label weights), nodes in the image's frame (voxel
// (i, j, k)'s centre at (i vx, j vy, k vz)). Throws std::runtime_error.
Tet_mesh mesh_image(const std::vector<uint8_t> &tissue, const int n[3], const double voxel[3],
                    const std::vector<uint8_t> *weights, const Criteria &criteria,
                    const Progress &progress);

// A closed triangulated surface meshed (mesh_surface.cpp): every
// tetrahedron in tissue 1. Throws std::runtime_error, naming the first two
// facets that intersect when the surface does.
Tet_mesh mesh_surface(const std::vector<double> &xyz, const std::vector<int32_t> &triangles,
                      const Criteria &criteria, const Progress &progress,
                      const std::string &name);

} // namespace ftm_mesher

#endif
