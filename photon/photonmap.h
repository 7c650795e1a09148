/* photonmap.h: the photon maps one render uses, as the coordinator builds
 * them and a worker receives them: the global map, the caustic map and the
 * precomputed-irradiance map (Christensen 1999), each a pointer-free kd-tree,
 * with the parameters their estimates need. Owned as a unit. */
#ifndef PF_PHOTONMAP_H
#define PF_PHOTONMAP_H

#include <stdint.h>
#include <string.h>

#include "accel/accel.h"
#include "photon/kdtree.h"

typedef struct pf_photon_maps {
    pf_kdtree_t *global;      /* photons on non-specular surfaces, any path; flux already divided by emitted count */
    pf_kdtree_t *caustic;     /* photons of L S+ D paths */
    pf_kdtree_t *irradiance;  /* irradiance (in power[]) at a subset of global photons */
    /* Under a path-length limit of 3 or more: the same points' irradiance
     * from the photons a gather from the camera's second vertex may take
     * (one bounce fewer), so those gathers read points too instead of
     * estimating from the global map. Not in the blob: whoever renders
     * derives it (pf_photon_deep_irradiance); NULL otherwise. */
    pf_kdtree_t *irradiance_deep;
    uint64_t global_emitted, caustic_emitted;
    float global_r2;          /* max squared search radius of global estimates */
    float caustic_r2;         /* max squared search radius of caustic estimates */
    float irradiance_r2;      /* max squared distance to an irradiance point */
    /* Gather rays shorter than this end at a near surface, whose points'
     * blur (their support) would show: twice the median support of the
     * irradiance points (pf_photon_maps_index derives it, not in the blob;
     * 0 without points). */
    float near_r;
} pf_photon_maps_t;

/* Readies the maps for rendering: sets near_r, and builds the irradiance
 * tree's nearest-point grid (pf_kdtree_index_nearest), which makes direct
 * lookups several times faster without changing a result. 0 or PF_ENOMEM
 * (the maps stay usable, only slower). The render's frame (render/frame.h) calls it,
 * then builds the irradiance texels (irrtex.h) over the maps. */
int pf_photon_maps_index(pf_photon_maps_t *maps);

/* Frees the trees; NULL-safe; leaves the struct zeroed. */
void pf_photon_maps_free(pf_photon_maps_t *maps);

/* Photons whose stored normal has a cosine below this with the query normal
 * lie on another surface (or the other side) and are left out of estimates. */
#define PF_NORMAL_AGREE 0.7f
/* Most photons one estimate may gather. */
#define PF_MAX_K 1024
/* The working memory every estimate below takes (one per thread): the
 * photons within a search radius, and their keys to select the k-th among. */
#define PF_PM_FOUND (2 * PF_MAX_K)
typedef struct pf_pm_scratch {
    pf_knn_t found[PF_PM_FOUND];
    uint64_t keys[PF_PM_FOUND];
    /* The path-length limit of the estimates made with this scratch
     * (pbrt's maxdepth, settings.path_max_depth): 0, every photon counts;
     * n > 0, only photons with fewer than n bounces (pf_photon_bounce).
     * The disc stays the k nearest photons' of any count, so the estimate
     * is that of the counted photons' flux over the same area (unbiased,
     * as the full one, for a uniform density of each). Whoever allocates
     * the scratch sets it. */
    unsigned bounce_limit;
    /* Out: the part of the last estimate (pf_pm_estimate's family,
     * pf_pm_irradiance_seen) its photons at their first hit (bounce 0, the
     * light's direct) carried. */
    pf_vec3 direct;
} pf_pm_scratch_t;

/* Whether photon p counts under bounce_limit (pf_pm_scratch_t). */
static inline int pf_photon_counts(const pf_photon_t *p, unsigned bounce_limit)
{
    return bounce_limit == 0 || pf_photon_bounce(p) < bounce_limit;
}

/* The bounce_limit that lets photons make at most `allowed` bounces, under
 * a path-length limit depth (0: none): 0 (all) without one or where allowed
 * reaches PF_PHOTON_BOUNCE_MAX (the count saturates there). allowed >= 0. */
static inline unsigned pf_pm_bounce_limit(int depth, int allowed)
{
    if (depth <= 0 || allowed >= (int)PF_PHOTON_BOUNCE_MAX)
        return 0;
    return (unsigned)allowed + 1u;
}

/* Irradiance (W/m^2) at x on the surface with unit normal n: the flux of the
 * k - 1 nearest photons whose normals agree, over the disc pi r^2, r the
 * distance to the k-th photon (unbiased for a uniform density); when fewer
 * than k lie within max_r2, all of them over pi max_r2.
 * k <= PF_MAX_K (more is taken as PF_MAX_K). The photons are summed in an order that depends only on the
 * map and x, so the estimate does too, bit for bit. */
pf_vec3 pf_pm_irradiance(const pf_kdtree_t *map, pf_vec3 x, pf_vec3 n, int k, float max_r2, pf_pm_scratch_t *scratch,
                         float *r2_out);

/* The same estimate, searched first within hint_r2 (a guess at the k-th
 * photon's squared distance, from a nearby estimate): the same result as
 * pf_pm_irradiance, bit for bit, faster when the guess holds k photons (and
 * not many times more), a second search when it does not. A hint of max_r2
 * itself (finite) guesses that fewer than k photons lie within it, as when
 * the nearby estimate found fewer: one radius search then finds them all.
 * A hint above max_r2 (INFINITY): none. */
pf_vec3 pf_pm_irradiance_hint(const pf_kdtree_t *map, pf_vec3 x, pf_vec3 n, int k, float max_r2, float hint_r2,
                              pf_pm_scratch_t *scratch, float *r2_out);

/* The radius of the disc an irradiance point's estimate averaged over (its
 * support), kept in the point's otherwise unused direction field: a float
 * whose sign bit is the point's flat flag (pf_irradiance_flat) and whose 8
 * lowest mantissa bits hold its direct share (below); the radius is the
 * float with those cleared (rounded down by at most 2^-15 of itself). */
#define PF_IRRADIANCE_FLAT_BIT 0x80000000u
#define PF_IRRADIANCE_SHARE_BITS 0xFFu
static inline float pf_irradiance_radius(const pf_photon_t *p)
{
    uint32_t u = p->dir & ~(PF_IRRADIANCE_FLAT_BIT | PF_IRRADIANCE_SHARE_BITS);
    float r;
    memcpy(&r, &u, sizeof r);
    return r;
}

/* The share of a point's irradiance (by luminance) its photons at their
 * first hit carried, the light's direct part, in [0, 1] to 1/255: a near
 * gather ray's end samples its direct light itself and takes the rest,
 * E (1 - share), from the point (render.c). */
static inline float pf_irradiance_direct_share(const pf_photon_t *p)
{
    return (float)(p->dir & PF_IRRADIANCE_SHARE_BITS) * (1.0f / 255.0f);
}

/* The direction field of an irradiance point: support radius r (>= 0), the
 * flat flag and the direct share, as the accessors above read them. */
static inline uint32_t pf_irradiance_pack(float r, int flat, float share)
{
    uint32_t u;
    memcpy(&u, &r, sizeof u);
    float q = share * 255.0f + 0.5f;
    u = (u & ~PF_IRRADIANCE_SHARE_BITS) | (uint32_t)(q > 255.0f ? 255.0f : q > 0.0f ? q : 0.0f);
    return flat ? u | PF_IRRADIANCE_FLAT_BIT : u;
}

/* Set when no surface but the point's own plane comes within
 * PF_IRRADIANCE_FLAT_REACH times its support radius (pf_accel_only_plane,
 * at precompute time). A lookup p within the support of such a point q lies
 * on that plane, and the leak test's ray, from p and q both lifted by their
 * distance d, runs inside that ball above the plane: it can hit nothing once
 * d clears the plane's tolerance (pf_irradiance_leak_test). */
#define PF_IRRADIANCE_FLAT_REACH 1.5f
static inline int pf_irradiance_flat(const pf_photon_t *p) { return (p->dir & PF_IRRADIANCE_FLAT_BIT) != 0; }

/* Whether a lookup at distance d from irradiance point q needs the leak
 * test's visibility ray (eps: pf_accel_eps). Not when d is within eps (no
 * wall fits between), nor when q is flat and d lifts the ray above what the
 * plane's tolerance allows: eps for the plane through q, eps and the tilt
 * over the radius for p's triangle, the tilt over the reach for any other
 * triangle of the plane (3 eps + 2.5 tilt r), with a margin. */
static inline int pf_irradiance_leak_test(const pf_photon_t *q, float d, float eps)
{
    if (!(d > eps))
        return 0;
    return !(pf_irradiance_flat(q) && d > 4.0f * eps + 3.0f * PF_ACCEL_PLANE_TILT * pf_irradiance_radius(q));
}

/* The leak test's ray for a lookup at p (face normal nf, towards the viewer)
 * answered by q at distance d: from p to q, both lifted by d along nf; the
 * lookup reads q's irradiance only when this segment (of length *len) hits
 * nothing. 0 when p and q coincide once lifted (nothing to trace). */
static inline int pf_irradiance_leak_ray(pf_vec3 p, pf_vec3 nf, const pf_photon_t *q, float d, pf_ray_t *ray,
                                         float *len)
{
    pf_vec3 a = pf_madd(p, nf, d), b = pf_madd(pf_photon_pos(q), nf, d);
    pf_vec3 ab = pf_sub(b, a);
    *len = pf_len(ab);
    if (!(*len > 0.0f))
        return 0;
    *ray = (pf_ray_t){ a, pf_scale(ab, 1.0f / *len) };
    return 1;
}

/* Irradiance at p (face normal nf, towards the viewer) from the
 * precomputed points irr (squared reach irr_r2): that of the nearest point q
 * with an agreeing normal, if p lies within q's support (the disc its
 * estimate averaged over) and q is visible from p (the leak test's ray,
 * where q is not flat); where the nearest does not answer, the next
 * nearest that does among the 8 nearest (a post or a chair's leg between
 * p and its nearest point); zero when none does, since then no photon
 * landed near p on its side of any wall. Without the visibility test the
 * final gather reads light through walls (the stress suite's thin wall and
 * closed crate). Safe from any thread once irr is indexed or not. */
pf_vec3 pf_irradiance_lookup(const pf_kdtree_t *irr, float irr_r2, const pf_accel_t *accel, pf_vec3 p, pf_vec3 nf);
/* The point that lookup reads (NULL: none answers). */
const pf_photon_t *pf_irradiance_lookup_point(const pf_kdtree_t *irr, float irr_r2, const pf_accel_t *accel, pf_vec3 p,
                                              pf_vec3 nf);

/* The same with a cone filter (Jensen 2001, 7.2.2, k = 1): weight
 * 1 - d / r, normalized by 1 - 2 / 3 over the disc, which sharpens caustics.
 * The squared radius the estimate used goes to *r2_out unless NULL; hint_r2
 * as in pf_pm_irradiance_hint. */
pf_vec3 pf_pm_irradiance_cone(const pf_kdtree_t *map, pf_vec3 x, pf_vec3 n, int k, float max_r2, float hint_r2,
                              pf_pm_scratch_t *scratch, float *r2_out);

/* Progressive passes (Knaus and Zwicker 2011, "Progressive photon mapping:
 * a probabilistic approach"): pass i's estimates average over a disc whose
 * squared radius is pf_pass_shrink2(i) times the k-nearest one, the product
 * of (j + alpha) / (j + 1) for j = 1..i. Each pass's photons are
 * independent; the mean of the passes then converges to the right answer,
 * bias (the blur, ~ r^2) and noise (~ 1 / (i r^2) per pass) both going to
 * zero, for 0 < alpha < 1; 2/3 balances them. The disc's photons are the
 * k nearest (or all within max_r2) whatever the pass: with the photons of a
 * k-nearest disc uniform in it, those within the shrunk disc estimate the
 * same density (E[count] = (k - 1) shrink2), so a pass's expected estimate
 * is the blur over the shrunk disc. Pass 0 is the unshrunk estimate. */
#define PF_PASS_ALPHA (2.0 / 3.0)
float pf_pass_shrink2(int pass);

/* The estimates above, with the disc shrunk by shrink2 (<= 1; 1: none,
 * the same bits as without) and a constant kernel (cone 0) or the cone
 * filter (cone 1). *r2_out (unless NULL) gets the unshrunk squared radius,
 * for hints. */
pf_vec3 pf_pm_estimate(const pf_kdtree_t *map, pf_vec3 x, pf_vec3 n, int k, float max_r2, float hint_r2,
                       float shrink2, int cone, pf_pm_scratch_t *scratch, float *r2_out);

/* Reflected radiance towards wo at x for a DIFFUSE material with a Phong
 * lobe, from the photons' directions (Jensen's original estimate): sum of
 * f(wi_p, wo) flux_p / (pi r^2), over the disc shrunk by shrink2 (as
 * pf_pm_estimate). Used where precomputed irradiance cannot represent the
 * reflection (glossy surfaces). */
struct pf_material;
pf_vec3 pf_pm_radiance(const pf_kdtree_t *map, const struct pf_material *m, pf_vec3 x, pf_vec3 n, pf_vec3 wo, int k,
                       float max_r2, float shrink2, pf_pm_scratch_t *scratch);

/* The most surfaces near a point whose planes spare the visibility rays
 * (pf_accel_near_planes); near more, every photon's ray is traced. */
#define PF_PM_VISIBLE_PLANES 32
/* How far off x's tangent plane a photon of the irradiance precompute's
 * estimate at a point near other surfaces may lie, over its distance from
 * x (the sine of its elevation). Photons of a parallel surface above or
 * below x (a chair's seat over the floor beneath it, a shelf) share x's
 * normal but not its surface; on a curved surface of radius R a photon at
 * distance d lies d / (2 R) off the plane, kept out to d = R, beyond which
 * its normal leaves the normal test's cone anyway. */
#define PF_PM_SLAB 0.5f

/* Working memory of pf_pm_irradiance_seen (one per thread): room for
 * cap photons of a radius search and their keys. */
typedef struct pf_pm_visible_scratch {
    size_t cap;
    pf_knn_t *found;   /* cap entries */
    uint64_t *keys;    /* cap entries */
    uint64_t *visible; /* PF_MAX_K entries */
    pf_plane_t planes[PF_PM_VISIBLE_PLANES];
} pf_pm_visible_scratch_t;

/* Allocates scratch for radius searches of up to cap photons (cap >=
 * PF_PM_FOUND); 0 or PF_ENOMEM. pf_pm_visible_scratch_free frees it
 * (NULL-safe, zeroes the struct). */
int pf_pm_visible_scratch_init(pf_pm_visible_scratch_t *vs, size_t cap);
void pf_pm_visible_scratch_free(pf_pm_visible_scratch_t *vs);

/* pf_pm_estimate's (constant kernel, the disc shrunk by shrink2) at x
 * (unit normal n) over the photons that x can see, for the irradiance
 * precompute; *r2_out gets the unshrunk squared radius and *flat_out the point's flat flag (pf_accel_only_plane
 * within PF_IRRADIANCE_FLAT_REACH of that radius; 0 without accel).
 * A photon at distance d is hidden when the segment from x lifted by d
 * along n to the photon lifted by d along its own normal hits a surface of
 * accel (for a photon of x's plane, the leak test's ray,
 * pf_irradiance_leak_ray); within pf_accel_eps of x it is seen. Where the
 * point is flat, or the k - 1 photons of the estimate are all seen, the
 * estimate is pf_pm_estimate's, bit for bit, and no ray is traced
 * for a flat point. Otherwise it is the same estimate over the seen
 * photons alone: the k - 1 nearest seen ones over the disc of the k-th seen
 * one (or all seen within max_r2 over that disc). Unlike pf_pm_estimate,
 * where fewer than an eighth of the k nearest photons agree with n (x on
 * the dim side of a sheet lit far more on its other side) the photons
 * counted are the k nearest that agree, within 64 times the first disc's
 * area: the disc, and the point's support, are then of x's own side's
 * density (photonmap.c, s_gather). At a point that is not flat the sum
 * keeps only the photons within x's slab (PF_PM_SLAB). A pure function of the
 * map, accel and the query, whatever the hint. k <= PF_MAX_K. */
pf_vec3 pf_pm_irradiance_seen(const pf_kdtree_t *map, const pf_accel_t *accel, pf_vec3 x, pf_vec3 n, int k,
                              float max_r2, float hint_r2, float shrink2, pf_pm_scratch_t *scratch,
                              pf_pm_visible_scratch_t *vs, float *r2_out, int *flat_out);

#endif
