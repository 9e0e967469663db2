// SPDX-License-Identifier: GPL-3.0-or-later
// What the two CGAL meshing paths share: the optimisation rounds and the
// copy of a complex into a Tet_mesh. Templates over the complex, so each
// path (one translation unit each, CGAL's templates are heavy) instantiates
// its own.
#ifndef FTM_MESHER_CGAL_COMMON_H
#define FTM_MESHER_CGAL_COMMON_H

#include "mesher.h"

#include <CGAL/exude_mesh_3.h>
#include <CGAL/perturb_mesh_3.h>

#include <chrono>
#include <cstdio>
#include <map>

namespace ftm_mesher {

inline double seconds_since(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

template <class C3t3> double complex_min_dihedral(const C3t3 &c3t3, size_t *below, double bound)
{
    double m = 180;
    size_t n = 0;
    for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
        double p[4][3];
        for (int i = 0; i < 4; i++) {
            const auto q = c->vertex(i)->point().point();
            p[i][0] = q.x(), p[i][1] = q.y(), p[i][2] = q.z();
        }
        double a = min_dihedral(p[0], p[1], p[2], p[3]);
        m = a < m ? a : m;
        n += a < bound;
    }
    if (below)
        *below = n;
    return m;
}

// Sliver perturbation and exudation, in rounds while they still improve the
// worst angle (a second round often lifts what the first left): CGAL's
// refinement bounds the radius-edge ratio, not the dihedral angles. No time
// limits, so the result does not depend on the machine's speed.
template <class C3t3, class Domain>
void optimise(C3t3 &c3t3, const Domain &domain, const Criteria &criteria,
              const Progress &progress)
{
    const double bound = criteria.min_angle + 2; // a margin: the rounds stop at the bound
    double worst = complex_min_dihedral(c3t3, nullptr, criteria.min_angle);
    for (int round = 1; round <= 3 && worst < criteria.min_angle; round++) {
        const auto t0 = std::chrono::steady_clock::now();
        CGAL::perturb_mesh_3(c3t3, domain, CGAL::parameters::time_limit = 0,
                             CGAL::parameters::sliver_bound = bound);
        CGAL::exude_mesh_3(c3t3, CGAL::parameters::time_limit = 0,
                           CGAL::parameters::sliver_bound = bound);
        size_t below = 0;
        double now = complex_min_dihedral(c3t3, &below, criteria.min_angle);
        char line[200];
        std::snprintf(line, sizeof line,
                      "optimised (round %d: perturbation, exudation) in %.1f s: smallest "
                      "dihedral angle %.2f degrees (was %.2f), %zu elements below %g",
                      round, seconds_since(t0), now, worst, below, criteria.min_angle);
        progress(line);
        if (!(now > worst))
            break;
        worst = now;
    }
}

// The complex's cells as a Tet_mesh: only the nodes they use, numbered in
// the order the cells first use them; tissue = subdomain index (mapped by
// tissue_of); every tetrahedron with positive volume.
template <class C3t3, class Tissue_of>
Tet_mesh to_tet_mesh(const C3t3 &c3t3, Tissue_of tissue_of)
{
    Tet_mesh m;
    std::map<typename C3t3::Vertex_handle, int32_t> index;
    for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
        int32_t v[4];
        for (int i = 0; i < 4; i++) {
            auto h = c->vertex(i);
            auto it = index.find(h);
            if (it == index.end()) {
                it = index.emplace(h, (int32_t)index.size()).first;
                const auto q = h->point().point();
                m.xyz.push_back(q.x());
                m.xyz.push_back(q.y());
                m.xyz.push_back(q.z());
            }
            v[i] = it->second;
        }
        const double *a = &m.xyz[3 * (size_t)v[0]], *b = &m.xyz[3 * (size_t)v[1]],
                     *cc = &m.xyz[3 * (size_t)v[2]], *d = &m.xyz[3 * (size_t)v[3]];
        double u[3], w[3], z[3];
        for (int k = 0; k < 3; k++) {
            u[k] = b[k] - a[k];
            w[k] = cc[k] - a[k];
            z[k] = d[k] - a[k];
        }
        double vol = u[0] * (w[1] * z[2] - w[2] * z[1]) - u[1] * (w[0] * z[2] - w[2] * z[0]) +
                     u[2] * (w[0] * z[1] - w[1] * z[0]);
        if (vol < 0)
            std::swap(v[2], v[3]);
        m.tets.insert(m.tets.end(), v, v + 4);
        m.tissue.push_back(tissue_of(c3t3.subdomain_index(c)));
    }
    return m;
}

} // namespace ftm_mesher

#endif
