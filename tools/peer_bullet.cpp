/* SPDX-License-Identifier: GPL-3.0-or-later */
// A body in Bullet's btSoftBody for `ftm bench peers`; see peer_bullet.h.
#include "peer_bullet.h"

#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <btBulletDynamicsCommon.h>

#include <cstdio>
#include <map>
#include <new>
#include <vector>

struct ftm_peer_bullet {
    btSoftBodyRigidBodyCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btSoftRigidDynamicsWorld world{&dispatcher, &broadphase, &solver, &config};
    btSoftBody *body = nullptr;
    std::vector<std::pair<btSoftBody::Material *, double>> materials; // and their weight
    std::vector<std::pair<int, btVector3>> loads;
};

extern "C" const char *ftm_peer_bullet_version(void)
{
    static char v[16];
    int n = btGetVersion();
    snprintf(v, sizeof v, "%d.%02d", n / 100, n % 100);
    return v;
}

extern "C" const char *ftm_peer_bullet_scalar(void)
{
    return sizeof(btScalar) == sizeof(double) ? "double" : "float";
}

extern "C" ftm_peer_bullet *ftm_peer_bullet_create(int32_t n, const double *x, const double *mass,
                                                   int32_t nlinks, const int32_t *pairs,
                                                   const double *weight, double damping)
{
    ftm_peer_bullet *p = new (std::nothrow) ftm_peer_bullet;
    if (!p)
        return nullptr;
    try {
        p->world.setGravity(btVector3(0, 0, 0));
        btSoftBodyWorldInfo &info = p->world.getWorldInfo();
        info.m_gravity = btVector3(0, 0, 0);
        std::vector<btVector3> pos((size_t)n);
        std::vector<btScalar> m((size_t)n);
        for (int32_t i = 0; i < n; i++) {
            pos[(size_t)i] = btVector3((btScalar)x[3 * i], (btScalar)x[3 * i + 1],
                                       (btScalar)x[3 * i + 2]);
            m[(size_t)i] = (btScalar)mass[i]; // 0: an inverse mass of 0, fixed
        }
        p->body = new btSoftBody(&info, n, pos.data(), m.data());
        // a material per weight (the links between nodes of the same two masses)
        std::map<double, btSoftBody::Material *> by_weight;
        for (int32_t l = 0; l < nlinks; l++) {
            btSoftBody::Material *&mat = by_weight[weight[l]];
            if (!mat) {
                mat = p->body->appendMaterial();
                p->materials.emplace_back(mat, weight[l]);
            }
            // no check for an existing link (quadratic): the pairs are distinct
            p->body->appendLink(pairs[2 * l], pairs[2 * l + 1], mat, false);
        }
        p->body->m_cfg.kDP = (btScalar)damping;
        p->world.addSoftBody(p->body);
    } catch (const std::bad_alloc &) {
        ftm_peer_bullet_destroy(p);
        return nullptr;
    }
    return p;
}

extern "C" void ftm_peer_bullet_destroy(ftm_peer_bullet *p)
{
    if (!p)
        return;
    if (p->body) {
        p->world.removeSoftBody(p->body);
        delete p->body;
    }
    delete p;
}

extern "C" void ftm_peer_bullet_set_scale(ftm_peer_bullet *p, double scale, double *lo, double *hi)
{
    double a = 2, b = 0;
    for (auto &mw : p->materials) {
        double k = scale * mw.second;
        k = k > 1 ? 1 : k;
        mw.first->m_kLST = (btScalar)k;
        a = k < a ? k : a;
        b = k > b ? k : b;
    }
    // the links' constants; not updateConstants (m_bUpdateRtCst), which also
    // takes the links' present lengths as their rest lengths
    p->body->updateLinkConstants();
    *lo = a;
    *hi = b;
}

extern "C" int ftm_peer_bullet_iterations(const ftm_peer_bullet *p)
{
    return p->body->m_cfg.piterations;
}

extern "C" void ftm_peer_bullet_load(ftm_peer_bullet *p, int32_t node, double fx, double fy,
                                     double fz)
{
    p->loads.emplace_back((int)node, btVector3((btScalar)fx, (btScalar)fy, (btScalar)fz));
}

static void apply_loads(ftm_peer_bullet *p)
{
    for (const auto &l : p->loads)
        p->body->addForce(l.second, l.first);
}

extern "C" void ftm_peer_bullet_step(ftm_peer_bullet *p, double h)
{
    apply_loads(p);
    p->body->predictMotion((btScalar)h);
    p->body->solveConstraints();
    p->body->integrateMotion();
}

extern "C" void ftm_peer_bullet_step_world(ftm_peer_bullet *p, double h)
{
    apply_loads(p);
    p->world.stepSimulation((btScalar)h, 0); // no substeps: one step of h
}

extern "C" void ftm_peer_bullet_positions(const ftm_peer_bullet *p, double *x)
{
    const btSoftBody::tNodeArray &nodes = p->body->m_nodes;
    for (int i = 0; i < nodes.size(); i++)
        for (int c = 0; c < 3; c++)
            x[3 * i + c] = nodes[i].m_x[c];
}

extern "C" void ftm_peer_bullet_set_positions(ftm_peer_bullet *p, const double *x)
{
    btSoftBody::tNodeArray &nodes = p->body->m_nodes;
    for (int i = 0; i < nodes.size(); i++) {
        nodes[i].m_x = btVector3((btScalar)x[3 * i], (btScalar)x[3 * i + 1], (btScalar)x[3 * i + 2]);
        nodes[i].m_q = nodes[i].m_x;
        nodes[i].m_v = btVector3(0, 0, 0);
    }
}
