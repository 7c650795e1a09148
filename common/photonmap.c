/* photonmap.c: density estimates over photon maps; see photonmap.h. Pure
 * functions of the maps and the query, safe from any thread. Sums run in
 * double in the order the kd-tree returns photons, so results are
 * reproducible bit for bit. */
#include "common/photonmap.h"

#include <string.h>

#include "common/bsdf.h"
#include "common/photon.h"
#include "common/status.h"

void pf_photon_maps_free(pf_photon_maps_t *maps)
{
    if (!maps)
        return;
    pf_kdtree_destroy(&maps->global);
    pf_kdtree_destroy(&maps->caustic);
    pf_kdtree_destroy(&maps->irradiance);
    memset(maps, 0, sizeof *maps);
}

int pf_photon_maps_index(pf_photon_maps_t *maps)
{
    return maps->irradiance ? pf_kdtree_index_nearest(maps->irradiance) : PF_OK;
}

/* Gathers up to k photons; returns how many lie inside the disc and its
 * radius squared. */
static size_t s_gather(const pf_kdtree_t *map, pf_vec3 x, int k, float max_r2, float hint_r2, pf_knn_t *scratch,
                       float *r2)
{
    if (!map || pf_kdtree_size(map) == 0 || k <= 0)
        return 0;
    if (k > PF_MAX_K)
        k = PF_MAX_K;
    size_t n = 0;
    /* k photons within the hint are the k nearest of all (every photon
     * closer than the k-th is within it too), ties and all; otherwise the
     * search is repeated without it. Unsorted: the heap's root is the k-th. */
    if (hint_r2 < max_r2)
        n = pf_kdtree_knn_heap(map, x, (size_t)k, hint_r2, scratch);
    if (n < (size_t)k)
        n = pf_kdtree_knn_heap(map, x, (size_t)k, max_r2, scratch);
    if (n == (size_t)k && k > 1) {
        /* The k-th photon only marks the radius: for photons of density
         * lambda, E[(k - 1) / (pi r_k^2)] = lambda, while counting all k
         * overestimates by k / (k - 1) (1 % at k = 100; the furnace shows it).
         * It moves to the end, out of the n - 1 the estimate sums. */
        pf_knn_t kth = scratch[0];
        scratch[0] = scratch[n - 1];
        scratch[n - 1] = kth;
        *r2 = kth.d2;
        return n - 1;
    }
    *r2 = max_r2;
    return n;
}

pf_vec3 pf_pm_irradiance(const pf_kdtree_t *map, pf_vec3 x, pf_vec3 n, int k, float max_r2, pf_knn_t *scratch,
                         float *r2_out)
{
    return pf_pm_irradiance_hint(map, x, n, k, max_r2, max_r2, scratch, r2_out);
}

pf_vec3 pf_pm_irradiance_hint(const pf_kdtree_t *map, pf_vec3 x, pf_vec3 n, int k, float max_r2, float hint_r2,
                              pf_knn_t *scratch, float *r2_out)
{
    float r2 = max_r2;
    size_t cnt = s_gather(map, x, k, max_r2, hint_r2, scratch, &r2);
    if (r2_out)
        *r2_out = r2;
    if (cnt == 0 || !(r2 > 0.0f))
        return pf_v3s(0.0f);
    const pf_photon_t *ph = pf_kdtree_photons(map);
    double s[3] = { 0, 0, 0 };
    for (size_t i = 0; i < cnt; i++) {
        const pf_photon_t *p = &ph[scratch[i].index];
        if (pf_dot(pf_photon_normal(p), n) < PF_NORMAL_AGREE)
            continue;
        s[0] += p->power[0];
        s[1] += p->power[1];
        s[2] += p->power[2];
    }
    double inv = 1.0 / (PF_PI * (double)r2);
    return pf_v3((float)(s[0] * inv), (float)(s[1] * inv), (float)(s[2] * inv));
}

pf_vec3 pf_pm_irradiance_cone(const pf_kdtree_t *map, pf_vec3 x, pf_vec3 n, int k, float max_r2, float hint_r2,
                              pf_knn_t *scratch, float *r2_out)
{
    float r2 = max_r2;
    size_t cnt = s_gather(map, x, k, max_r2, hint_r2, scratch, &r2);
    if (r2_out)
        *r2_out = r2;
    if (cnt == 0 || !(r2 > 0.0f))
        return pf_v3s(0.0f);
    const pf_photon_t *ph = pf_kdtree_photons(map);
    double r = sqrt((double)r2);
    double s[3] = { 0, 0, 0 };
    for (size_t i = 0; i < cnt; i++) {
        const pf_photon_t *p = &ph[scratch[i].index];
        if (pf_dot(pf_photon_normal(p), n) < PF_NORMAL_AGREE)
            continue;
        double w = 1.0 - sqrt((double)scratch[i].d2) / r;
        if (w <= 0.0)
            continue;
        s[0] += w * p->power[0];
        s[1] += w * p->power[1];
        s[2] += w * p->power[2];
    }
    /* The cone of height 1 over the disc holds pi r^2 / 3; normalize to the disc. */
    double inv = 3.0 / (PF_PI * (double)r2);
    return pf_v3((float)(s[0] * inv), (float)(s[1] * inv), (float)(s[2] * inv));
}

pf_vec3 pf_pm_radiance(const pf_kdtree_t *map, const struct pf_material *m, pf_vec3 x, pf_vec3 n, pf_vec3 wo, int k,
                       float max_r2, pf_knn_t *scratch)
{
    float r2 = 0.0f;
    size_t cnt = s_gather(map, x, k, max_r2, max_r2, scratch, &r2);
    if (cnt == 0 || !(r2 > 0.0f))
        return pf_v3s(0.0f);
    const pf_photon_t *ph = pf_kdtree_photons(map);
    double s[3] = { 0, 0, 0 };
    for (size_t i = 0; i < cnt; i++) {
        const pf_photon_t *p = &ph[scratch[i].index];
        if (pf_dot(pf_photon_normal(p), n) < PF_NORMAL_AGREE)
            continue;
        pf_vec3 wi = pf_neg(pf_oct_decode(p->dir));
        pf_vec3 f = pf_brdf_eval(m, n, wi, wo);
        s[0] += f.x * p->power[0];
        s[1] += f.y * p->power[1];
        s[2] += f.z * p->power[2];
    }
    double inv = 1.0 / (PF_PI * (double)r2);
    return pf_v3((float)(s[0] * inv), (float)(s[1] * inv), (float)(s[2] * inv));
}
