// SPDX-License-Identifier: GPL-3.0-or-later
// A closed surface (an STL) meshed with CGAL's Mesh_3 inside it: its
// facets approximate the surface, every tetrahedron one tissue.
#include "cgal_common.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polyhedral_mesh_domain_3.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/make_mesh_3.h>

#include <iterator>
#include <stdexcept>

namespace ftm_mesher {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Surface = CGAL::Surface_mesh<K::Point_3>;
using Domain = CGAL::Polyhedral_mesh_domain_3<Surface, K>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
using Mesh_criteria = CGAL::Mesh_criteria_3<Tr>;

} // namespace

Tet_mesh mesh_surface(const std::vector<double> &xyz, const std::vector<int32_t> &triangles,
                      const Criteria &criteria, const Progress &progress,
                      const std::string &name)
{
    CGAL::get_default_random() = CGAL::Random(0); // as mesh_image: the same mesh every run
    namespace p = CGAL::parameters;
    const auto t0 = std::chrono::steady_clock::now();
    Surface s;
    std::vector<Surface::Vertex_index> v;
    for (size_t i = 0; i < xyz.size() / 3; i++)
        v.push_back(s.add_vertex(K::Point_3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2])));
    for (size_t t = 0; t < triangles.size() / 3; t++) {
        Surface::Face_index f =
            s.add_face(v[triangles[3 * t]], v[triangles[3 * t + 1]], v[triangles[3 * t + 2]]);
        if (f == Surface::null_face()) // closed and oriented (ftm_surface_load), yet not a 2-manifold
            throw std::runtime_error(name + ": facet " + std::to_string(t + 1) +
                                     " makes the surface non-manifold (three or more facets "
                                     "meet at one of its edges or corners)");
    }
    // a surface crossing itself has no inside to mesh: refused, naming two
    // facets (faces are numbered as added: the file's facet order)
    std::vector<std::pair<Surface::Face_index, Surface::Face_index>> pairs;
    CGAL::Polygon_mesh_processing::self_intersections(s, std::back_inserter(pairs));
    if (!pairs.empty()) {
        size_t a = (size_t)pairs[0].first + 1, b = (size_t)pairs[0].second + 1;
        throw std::runtime_error(name + ": the surface intersects itself: facets " +
                                 std::to_string(std::min(a, b)) + " and " +
                                 std::to_string(std::max(a, b)) + " cross (" +
                                 std::to_string(pairs.size()) + " pairs in all)");
    }
    Domain domain(s);
    const double L = criteria.size;
    Mesh_criteria mc(p::facet_angle = 30, p::facet_size = L / std::sqrt(3.0),
                     p::facet_distance = criteria.facet_distance, p::cell_radius_edge_ratio = 2,
                     p::cell_size = L * std::sqrt(6.0) / 4);
    C3t3 c3t3 = CGAL::make_mesh_3<C3t3>(domain, mc, p::no_perturb(), p::no_exude());
    char line[200];
    std::snprintf(line, sizeof line, "refined in %.1f s: %zu tetrahedra, %zu boundary facets",
                  seconds_since(t0), (size_t)c3t3.number_of_cells_in_complex(),
                  (size_t)c3t3.number_of_facets_in_complex());
    progress(line);
    optimise(c3t3, domain, criteria, progress);
    return to_tet_mesh(c3t3, [](int) { return (int32_t)1; });
}

} // namespace ftm_mesher
