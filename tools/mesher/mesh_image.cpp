// SPDX-License-Identifier: GPL-3.0-or-later
// A labelled image meshed with CGAL's 3D mesh generation (Mesh_3): a
// Delaunay refinement whose facets follow every boundary between two labels,
// so the tissues conform where they meet (the approach of SOFA's CGAL
// plugin). Then sliver perturbation and exudation (cgal_common.h).
#include "cgal_common.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Image_3.h>
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_3/initialize_triangulation_from_labeled_image.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/make_mesh_3.h>

#include <algorithm>
#include <iostream>
#include <sstream>
#include <stdexcept>

namespace ftm_mesher {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Domain = CGAL::Labeled_mesh_domain_3<K>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
using Mesh_criteria = CGAL::Mesh_criteria_3<Tr>;

// An 8-bit image CGAL owns, a copy of `data`.
CGAL::Image_3 image_of(const std::vector<uint8_t> &data, const int n[3], const double voxel[3])
{
    _image *im = _createImage((std::size_t)n[0], (std::size_t)n[1], (std::size_t)n[2], 1,
                              voxel[0], voxel[1], voxel[2], 1, WK_FIXED, SGN_UNSIGNED);
    if (!im)
        throw std::runtime_error("out of memory for the image");
    std::copy(data.begin(), data.end(), static_cast<uint8_t *>(im->data));
    return CGAL::Image_3(im);
}

} // namespace

Tet_mesh mesh_image(const std::vector<uint8_t> &tissue, const int n[3], const double voxel[3],
                    const std::vector<uint8_t> *weights, const Criteria &criteria,
                    const Progress &progress)
{
    // Mesh_3 draws its initial points from CGAL's default random generator,
    // which is seeded from the clock: a fixed seed gives the same mesh on
    // every run
    CGAL::get_default_random() = CGAL::Random(0);
    namespace p = CGAL::parameters;
    const auto t0 = std::chrono::steady_clock::now();
    CGAL::Image_3 image = image_of(tissue, n, voxel);
    CGAL::Image_3 weight_image;
    if (weights)
        weight_image = image_of(*weights, n, voxel);
    // the bisection along a segment stops at 1e-6 of the image's diagonal:
    // well below a voxel
    Domain domain =
        weights ? Domain::create_labeled_image_mesh_domain(image, p::weights = weight_image,
                                                           p::relative_error_bound = 1e-6)
                : Domain::create_labeled_image_mesh_domain(image, p::relative_error_bound = 1e-6);
    // size: a regular tetrahedron of edge L has circumradius L sqrt(6)/4, an
    // equilateral triangle L/sqrt(3); facet angles >= 30 degrees and a
    // radius-edge ratio <= 2 bound the shapes the refinement leaves
    const double L = criteria.size;
    Mesh_criteria mc(p::facet_angle = 30, p::facet_size = L / std::sqrt(3.0),
                     p::facet_distance = criteria.facet_distance, p::cell_radius_edge_ratio = 2,
                     p::cell_size = L * std::sqrt(6.0) / 4);
    C3t3 c3t3;
    // one seed point in every connected part of every label, so that small
    // parts are not missed by the refinement's initial points (it reports on
    // std::cout, where our summary goes: silenced)
    {
        std::ostringstream quiet;
        std::streambuf *was = std::cout.rdbuf(quiet.rdbuf());
        try {
            initialize_triangulation_from_labeled_image(c3t3, domain, image, mc,
                                                        (unsigned char)0);
        } catch (...) {
            std::cout.rdbuf(was);
            throw;
        }
        std::cout.rdbuf(was);
    }
    CGAL::refine_mesh_3(c3t3, domain, mc, p::no_perturb(), p::no_exude());
    char line[200];
    std::snprintf(line, sizeof line, "refined in %.1f s: %zu tetrahedra, %zu boundary facets",
                  seconds_since(t0), (size_t)c3t3.number_of_cells_in_complex(),
                  (size_t)c3t3.number_of_facets_in_complex());
    progress(line);
    optimise(c3t3, domain, criteria, progress);
    return to_tet_mesh(c3t3, [](int sd) { return (int32_t)sd; });
}

} // namespace ftm_mesher
