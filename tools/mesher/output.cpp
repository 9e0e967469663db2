// SPDX-License-Identifier: GPL-3.0-or-later
// Surface slivers, quality figures and the Gmsh writer (output.h).
#include "output.h"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace ftm_mesher {

double min_dihedral(const double *a, const double *b, const double *c, const double *d)
{
    const double *p[4] = {a, b, c, d};
    // the dihedral angle at edge (i, j) is between the faces (i, j, k) and
    // (i, j, l): the angle of their normals' projections
    static const int edge[6][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 3, 1, 2},
                                   {1, 2, 0, 3}, {1, 3, 0, 2}, {2, 3, 0, 1}};
    double m = 180;
    for (const auto &e : edge) {
        double u[3], v[3], w[3];
        for (int k = 0; k < 3; k++) {
            u[k] = p[e[1]][k] - p[e[0]][k];
            v[k] = p[e[2]][k] - p[e[0]][k];
            w[k] = p[e[3]][k] - p[e[0]][k];
        }
        double n1[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                        u[0] * v[1] - u[1] * v[0]};
        double n2[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                        u[0] * w[1] - u[1] * w[0]};
        double l1 = std::sqrt(n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2]);
        double l2 = std::sqrt(n2[0] * n2[0] + n2[1] * n2[1] + n2[2] * n2[2]);
        if (!(l1 > 0 && l2 > 0))
            return 0;
        double c = (n1[0] * n2[0] + n1[1] * n2[1] + n1[2] * n2[2]) / (l1 * l2);
        double angle = std::acos(std::max(-1.0, std::min(1.0, c))) * 180.0 / 3.14159265358979323846;
        m = std::min(m, angle);
    }
    return m;
}

static double tet_angle(const Tet_mesh &m, size_t t)
{
    const int32_t *v = &m.tets[4 * t];
    return min_dihedral(&m.xyz[3 * (size_t)v[0]], &m.xyz[3 * (size_t)v[1]],
                        &m.xyz[3 * (size_t)v[2]], &m.xyz[3 * (size_t)v[3]]);
}

size_t remove_surface_slivers(Tet_mesh &m, double min_angle)
{
    size_t removed = 0;
    for (int pass = 0; pass < 20; pass++) {
        // faces as sorted corner triples: a face of one tetrahedron only is
        // on the outer boundary
        std::vector<std::array<int32_t, 4>> faces; // 3 corners, then the tetrahedron
        faces.reserve(4 * m.tet_count());
        for (size_t t = 0; t < m.tet_count(); t++)
            for (int k = 0; k < 4; k++) {
                std::array<int32_t, 4> f{};
                int n = 0;
                for (int i = 0; i < 4; i++)
                    if (i != k)
                        f[(size_t)n++] = m.tets[4 * t + (size_t)i];
                std::sort(f.begin(), f.begin() + 3);
                f[3] = (int32_t)t;
                faces.push_back(f);
            }
        std::sort(faces.begin(), faces.end());
        std::vector<char> on_surface(m.tet_count(), 0);
        for (size_t i = 0; i < faces.size();) {
            size_t j = i + 1;
            while (j < faces.size() && std::equal(faces[j].begin(), faces[j].begin() + 3,
                                                  faces[i].begin()))
                j++;
            if (j - i == 1)
                on_surface[(size_t)faces[i][3]] = 1;
            i = j;
        }
        std::vector<char> drop(m.tet_count(), 0);
        size_t n = 0;
        for (size_t t = 0; t < m.tet_count(); t++)
            if (on_surface[t] && tet_angle(m, t) < min_angle) {
                drop[t] = 1;
                n++;
            }
        if (n == 0)
            break;
        Tet_mesh kept;
        kept.xyz = m.xyz;
        for (size_t t = 0; t < m.tet_count(); t++)
            if (!drop[t]) {
                kept.tets.insert(kept.tets.end(), &m.tets[4 * t], &m.tets[4 * t] + 4);
                kept.tissue.push_back(m.tissue[t]);
            }
        m = std::move(kept);
        removed += n;
    }
    // the nodes still used, in their order
    std::vector<int32_t> renum(m.xyz.size() / 3, -1);
    for (int32_t v : m.tets)
        renum[(size_t)v] = 0;
    std::vector<double> xyz;
    int32_t k = 0;
    for (size_t i = 0; i < renum.size(); i++)
        if (renum[i] == 0) {
            renum[i] = k++;
            xyz.insert(xyz.end(), &m.xyz[3 * i], &m.xyz[3 * i] + 3);
        }
    for (int32_t &v : m.tets)
        v = renum[(size_t)v];
    m.xyz.swap(xyz);
    return removed;
}

Quality quality(const Tet_mesh &m, int tissue_count, double bound)
{
    Quality q;
    q.per_tissue.assign((size_t)tissue_count + 1, 0);
    double edges = 0;
    for (size_t t = 0; t < m.tet_count(); t++) {
        double a = tet_angle(m, t);
        q.min_angle = std::min(q.min_angle, a);
        q.below += a < bound;
        if (m.tissue[t] >= 1 && m.tissue[t] <= tissue_count)
            q.per_tissue[(size_t)m.tissue[t]]++;
        const int32_t *v = &m.tets[4 * t];
        const double *p[4];
        for (int i = 0; i < 4; i++)
            p[i] = &m.xyz[3 * (size_t)v[i]];
        for (int i = 0; i < 4; i++)
            for (int j = i + 1; j < 4; j++)
                edges += std::sqrt((p[i][0] - p[j][0]) * (p[i][0] - p[j][0]) +
                                   (p[i][1] - p[j][1]) * (p[i][1] - p[j][1]) +
                                   (p[i][2] - p[j][2]) * (p[i][2] - p[j][2]));
        double u[3], w[3], z[3];
        for (int k = 0; k < 3; k++) {
            u[k] = p[1][k] - p[0][k];
            w[k] = p[2][k] - p[0][k];
            z[k] = p[3][k] - p[0][k];
        }
        q.volume += (u[0] * (w[1] * z[2] - w[2] * z[1]) - u[1] * (w[0] * z[2] - w[2] * z[0]) +
                     u[2] * (w[0] * z[1] - w[1] * z[0])) /
                    6;
    }
    q.mean_edge = m.tet_count() ? edges / (6.0 * (double)m.tet_count()) : 0;
    return q;
}

bool write_gmsh(const std::string &path, const Tet_mesh &m, const std::vector<std::string> &names,
                std::string *why)
{
    FILE *f = std::fopen(path.c_str(), "w");
    if (!f) {
        *why = path + ": cannot write: " + std::strerror(errno);
        return false;
    }
    const size_t nn = m.xyz.size() / 3, nt = m.tet_count(), ntis = names.size();
    std::fprintf(f, "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n");
    std::fprintf(f, "$PhysicalNames\n%zu\n", ntis);
    for (size_t t = 0; t < ntis; t++)
        std::fprintf(f, "3 %zu \"%s\"\n", t + 1, names[t].c_str());
    std::fprintf(f, "$EndPhysicalNames\n");
    // one volume entity per tissue, its bounding box, its physical group
    std::fprintf(f, "$Entities\n0 0 0 %zu\n", ntis);
    for (size_t t = 0; t < ntis; t++) {
        double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
        for (size_t e = 0; e < nt; e++)
            if (m.tissue[e] == (int32_t)(t + 1))
                for (int i = 0; i < 4; i++)
                    for (int k = 0; k < 3; k++) {
                        double x = m.xyz[3 * (size_t)m.tets[4 * e + (size_t)i] + (size_t)k];
                        lo[k] = std::min(lo[k], x);
                        hi[k] = std::max(hi[k], x);
                    }
        if (lo[0] > hi[0])
            lo[0] = lo[1] = lo[2] = hi[0] = hi[1] = hi[2] = 0;
        std::fprintf(f, "%zu %.17g %.17g %.17g %.17g %.17g %.17g 1 %zu 0\n", t + 1, lo[0], lo[1],
                     lo[2], hi[0], hi[1], hi[2], t + 1);
    }
    std::fprintf(f, "$EndEntities\n");
    std::fprintf(f, "$Nodes\n1 %zu 1 %zu\n3 1 0 %zu\n", nn, nn, nn);
    for (size_t i = 0; i < nn; i++)
        std::fprintf(f, "%zu\n", i + 1);
    for (size_t i = 0; i < nn; i++)
        std::fprintf(f, "%.17g %.17g %.17g\n", m.xyz[3 * i], m.xyz[3 * i + 1], m.xyz[3 * i + 2]);
    std::fprintf(f, "$EndNodes\n");
    size_t blocks = 0;
    std::vector<size_t> per(ntis + 1, 0);
    for (int32_t t : m.tissue)
        per[(size_t)t]++;
    for (size_t t = 1; t <= ntis; t++)
        blocks += per[t] > 0;
    std::fprintf(f, "$Elements\n%zu %zu 1 %zu\n", blocks, nt, nt);
    size_t tag = 1;
    for (size_t t = 1; t <= ntis; t++) {
        if (!per[t])
            continue;
        std::fprintf(f, "3 %zu 4 %zu\n", t, per[t]);
        for (size_t e = 0; e < nt; e++)
            if (m.tissue[e] == (int32_t)t) {
                const int32_t *v = &m.tets[4 * e];
                std::fprintf(f, "%zu %d %d %d %d\n", tag++, v[0] + 1, v[1] + 1, v[2] + 1,
                             v[3] + 1);
            }
    }
    std::fprintf(f, "$EndElements\n");
    bool ok = !std::ferror(f);
    if (std::fclose(f) != 0)
        ok = false;
    if (!ok)
        *why = path + ": cannot write: " + std::strerror(errno ? errno : EIO);
    return ok;
}

} // namespace ftm_mesher
