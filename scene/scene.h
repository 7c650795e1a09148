/* scene.h: the scene model shared by every stage: materials, triangle meshes,
 * analytic spheres, point/spot lights, the camera and the render settings.
 * The loaders in load/ (JSON, OBJ/MTL, PLY) fill it; pf_scene_finalize()
 * validates it and derives the area lights from emissive triangles.
 * A pf_scene_t owns everything it points to; pf_scene_destroy frees it. */
#ifndef PF_SCENE_H
#define PF_SCENE_H

#include <stddef.h>
#include <stdint.h>

#include "base/status.h"
#include "base/vec.h"
#include "scene/envmap.h"

/* Material kinds (the last is PF_MAT_LAST). Every kind may also emit (le), one-sided along the face
 * normal given by the triangle's counter-clockwise winding, or on both sides (twosided). */
typedef enum {
    PF_MAT_DIFFUSE = 0, /* Lambertian kd, plus an optional energy-conserving Phong lobe ks/ns */
    PF_MAT_MIRROR = 1,  /* perfect specular reflection with reflectance ks */
    PF_MAT_GLASS = 2,   /* smooth dielectric: Fresnel reflection tinted ks, refraction tinted kt, index ior */
    PF_MAT_CONDUCTOR = 3, /* metal: GGX microfacets of roughness alpha (0: smooth), complex index eta + i k per channel */
    PF_MAT_THIN_DIELECTRIC = 4, /* thin sheet of index ior (a window pane as one quad): reflects R' tinted ks,
                                 * passes 1 - R' unbent tinted kt, alike from both sides (pbrt-v4 thindielectric) */
    PF_MAT_COATED = 5, /* Lambertian kd under a dielectric coat of index ior, GGX roughness alpha (0: smooth)
                        * and thickness (pbrt-v4 coateddiffuse; material/coated.h) */
    PF_MAT_DIFFUSE_TRANSMISSION = 6, /* Lambertian reflection kd on the side light comes from and Lambertian
                                      * transmission kt to the other, alike from both sides (pbrt-v4
                                      * diffusetransmission; material/difftrans.h) */
    PF_MAT_MIX = 7, /* one of two materials, mix[1] with probability amount (or amount_tex), chosen at each hit
                     * by a hash of the hit (pbrt-v4 mix; accel/surface.c); its own le only */
} pf_mat_type;
#define PF_MAT_LAST PF_MAT_MIX
/* How deep MIX materials may nest (a mix of mixes); finalize rejects deeper chains and cycles. */
#define PF_MIX_MAX_DEPTH 8

#define PF_NAME_MAX 64

typedef struct pf_material {
    char name[PF_NAME_MAX];
    pf_mat_type type;
    pf_vec3 kd;  /* diffuse albedo (DIFFUSE, the base of COATED) */
    pf_vec3 ks;  /* Phong glossy albedo (DIFFUSE), reflectance (MIRROR), reflection tint (GLASS, THIN_DIELECTRIC) */
    float ns;    /* Phong exponent (DIFFUSE with ks > 0) */
    pf_vec3 kt;  /* transmission tint (GLASS, THIN_DIELECTRIC) */
    float ior;   /* index of refraction (GLASS, THIN_DIELECTRIC, the coat of COATED) */
    pf_vec3 eta; /* real part of the complex index of refraction (CONDUCTOR), > 0 */
    pf_vec3 k;   /* imaginary part, the extinction coefficient (CONDUCTOR), >= 0 */
    float alpha; /* GGX roughness alpha in [0, 1] (CONDUCTOR, COATED's coat); below 1e-3 a smooth mirror */
    float thickness; /* COATED: the coat's thickness, each crossing attenuates by exp(-thickness / |cos|)
                      * (pbrt-v4's layered BSDF, default 0.01 there); 0: lossless */
    pf_vec3 le;  /* emitted radiance, one-sided (the front) unless twosided */
    uint32_t twosided; /* 1: le leaves both sides of a triangle alike (pbrt-v4's two-sided DiffuseAreaLight; a
                        * quad so emits 2 pi A lum(le)); 0: the front only. Not on analytic spheres (finalize). */
    uint32_t kd_tex; /* 1 + index into pf_scene_t.texs: kd is that texture at the hit's uv; 0: kd as is */
    uint32_t mix[2];     /* MIX: the two materials' indices into pf_scene_t.mats */
    float amount;        /* MIX: the probability of mix[1] (pbrt's amount; <= 0: mix[0], >= 1: mix[1]) */
    uint32_t amount_tex; /* MIX: 1 + texture index: amount is that texture's mean channel at the hit; 0: amount */
    uint32_t alpha_tex;  /* 1 + texture index: an alpha cut-out of every triangle with this material (MTL map_d;
                          * accel/alpha.c), where its mesh has none of its own; 0: opaque */
    /* Textured slots beyond kd (accel/surface.h resolves them at a hit; 0: none): */
    uint32_t refl_tex;   /* CONDUCTOR: pbrt-v4's reflectance form, ks = the texture, eta 1, k from ks;
                          * DIFFUSE (a Phong lobe) and MIRROR: ks times the texture (MTL map_Ks), a
                          * Phong ks at most 1 - kd */
    uint32_t rough_tex;  /* CONDUCTOR, COATED: roughness texture (first channel); alpha = sqrt of it when
                          * rough_remap, else the value itself, clamped to [0, 1] */
    uint32_t rough_remap;
    uint32_t normal_tex; /* tangent-space normal map (linear RGB, n = 2 c - 1 in the (dpdu, n x dpdu, n) frame) */
    uint32_t bump_tex;   /* displacement (first channel, world units): bump mapping (accel/shading.h) */
    uint32_t kt_tex;     /* DIFFUSE_TRANSMISSION: kt is that texture at the hit's uv, clamped to [0, 1]; a
                          * textured sheet's kt is held to at most 1 - kd at each hit (it passes on no more
                          * than it receives) */
    /* The media on the surface's two sides, absorbing only (Beer-Lambert;
     * pbrt-v4's MediumInterface "inside" "outside" without the scattering):
     * absorption coefficients per world unit, 0 a clear medium. A ray that
     * reaches the surface from behind (against ng) has crossed sigma_in on
     * its way, from the front sigma_out (accel/surface.h,
     * pf_hit_transmittance), so a closed glass solid with sigma_in tints
     * the light by exp(-sigma_in d) over the length d it runs inside. */
    pf_vec3 sigma_in, sigma_out;
} pf_material_t;

/* pbrt-v4's "reflectance" form of a conductor: eta = 1 and this k, which
 * gives normal-incidence reflectance r ((1 - eta)^2 + k^2) / ((1 + eta)^2 + k^2)
 * = r; r is clamped to at most 0.9999 (r = 1 needs an infinite k). */
static inline float pf_conductor_k_of_reflectance(float r)
{
    r = r < 0.0f ? 0.0f : r > 0.9999f ? 0.9999f : r;
    return 2.0f * sqrtf(r) / sqrtf(1.0f - r);
}

/* A triangle mesh in world space. nrm is per vertex (shading normals) or
 * NULL; uv is per vertex (texture coordinates, 2 floats each) or NULL, when
 * a hit's uv is pbrt's default parametrization (scene/texture.h). */
typedef struct pf_mesh {
    char name[PF_NAME_MAX];
    size_t nverts, ntris;
    pf_vec3 *pos;    /* nverts */
    pf_vec3 *nrm;    /* nverts, unit length, or NULL */
    float *uv;       /* 2 * nverts, or NULL */
    uint32_t *idx;   /* 3 * ntris vertex indices */
    uint32_t *mat;   /* ntris material indices into pf_scene_t.mats */
    uint32_t alpha_tex; /* 1 + texture index: an alpha cut-out (accel/alpha.c); 0: opaque */
} pf_mesh_t;

typedef enum {
    PF_TEX_CONSTANT = 0, /* op[0] */
    PF_TEX_IMAGE = 1,    /* pixels, times scale, inverted (1 - v, clamped at 0) when invert */
    PF_TEX_CHECKER = 2,  /* op[0] where floor(s) + floor(t) is even, else op[1] (pbrt-v4 checkerboard, 2D) */
    PF_TEX_SCALE = 3,    /* op[0] * op[1] */
    PF_TEX_MIX = 4,      /* (1 - a) op[0] + a op[1], a = op[2]'s first channel */
} pf_tex_type;
#define PF_TEX_LAST PF_TEX_MIX

typedef enum { PF_WRAP_REPEAT = 0, PF_WRAP_CLAMP = 1, PF_WRAP_BLACK = 2 } pf_tex_wrap;
#define PF_WRAP_LAST PF_WRAP_BLACK

/* The largest image a texture may hold: each side and the pixel count. */
#define PF_TEX_MAX_SIDE 16384
#define PF_TEX_MAX_PIXELS (1u << 28)

/* An operand of a procedural: the texture ref (1 + index, earlier in the
 * table) when nonzero, else the constant c. */
typedef struct pf_tex_operand {
    pf_vec3 c;
    uint32_t ref;
} pf_tex_operand_t;

/* A texture (pbrt-v4's 2D textures on uv coordinates; scene/texture.h
 * evaluates them): an image (8-bit, sRGB-encoded or linear, or float linear
 * RGB) with bilinear lookup and a wrap mode, or a procedural (constant,
 * checkerboard, scale, mix) whose operands are constants or earlier
 * textures. The scene owns the pixels. */
typedef struct pf_texture {
    char name[PF_NAME_MAX];
    pf_tex_type type;
    /* pbrt's uv mapping: s = su u + du, t = sv v + dv. */
    float su, sv, du, dv;
    pf_tex_operand_t op[3];
    /* IMAGE: width x height RGB pixels, top row first, in px8 (8 bits,
     * sRGB-encoded when srgb, else linear v / 255) or pxf (linear float);
     * t = 0 is the bottom row, as in pbrt. */
    int width, height;
    pf_tex_wrap wrap;
    int srgb;
    float scale;
    int invert;
    uint8_t *px8;
    float *pxf;
} pf_texture_t;

typedef struct pf_sphere {
    pf_vec3 center;
    float radius;
    uint32_t mat;
} pf_sphere_t;

typedef enum { PF_LIGHT_POINT = 0, PF_LIGHT_SPOT = 1, PF_LIGHT_DISTANT = 2, PF_LIGHT_INFINITE = 3 } pf_light_type;
#define PF_LIGHT_LAST PF_LIGHT_INFINITE

/* Point, spot and distant lights (area lights come from emissive materials).
 * A distant light (the sun) sends parallel light along dir from infinitely
 * far away: intensity is then its irradiance on a surface perpendicular to
 * dir (W/m^2 per channel), and pos is unused. An infinite light (a
 * constant sky) surrounds the scene: every ray that escapes sees the
 * radiance in intensity; pos and dir are unused. An infinite light with a
 * map is an image-based sky: its radiance is intensity (the scale) times
 * the map's pixel in the direction seen (scene/envmap.h). */
typedef struct pf_light {
    pf_light_type type;
    pf_vec3 pos;
    pf_vec3 intensity;  /* radiant intensity, W/sr per channel, on the axis for spots; irradiance for distant;
                         * radiance for infinite */
    pf_vec3 dir;        /* spot axis, or the direction a distant light's light travels; unit */
    float cos_inner;    /* spot: full intensity inside this cone */
    float cos_outer;    /* spot: zero outside; smoothstep between */
    uint32_t map;       /* infinite: 1 + the index of its image in pf_scene_t.envmaps; 0: constant */
} pf_light_t;

/* The camera. All-zero extras give the pinhole camera of the JSON format:
 * fov along the vertical axis, image right = forward x up. */
typedef struct pf_camera_desc {
    pf_vec3 pos, look_at, up;
    float vfov_deg;       /* field of view (degrees) along the vertical axis, or the shorter one (fov_shorter) */
    int fov_shorter;      /* 1: vfov_deg spans the image's shorter axis (pbrt's "fov"), 0: the vertical one */
    int left_handed;      /* 1: image right = up x forward (pbrt's left-handed camera space), 0: forward x up */
    float lens_radius;    /* thin lens: radius of the aperture, world units; 0: pinhole */
    float focal_distance; /* thin lens: distance to the plane in focus (> 0 when lens_radius > 0) */
    /* pbrt's screen window, in units of tan(fov / 2) on the image plane at
     * distance 1 (scene/camera.h): with has_window, window = xmin, xmax,
     * ymin, ymax (xmin < xmax, ymin < ymax); without, the default one of
     * frame_aspect. frame_aspect is pbrt's "frameaspectratio" (> 0), or 0:
     * the image's width / height. */
    int has_window;
    float window[4];
    float frame_aspect;
} pf_camera_desc_t;

/* The largest settings.gather_filter: a (2n+1)^2 window of pixels. */
#define PF_MAX_GATHER_FILTER 8
/* Progressive passes one render may have (settings.pass < PF_MAX_PASSES). */
#define PF_MAX_PASSES (1 << 20)

/* Render settings: defaults from pf_settings_default(), then the scene file's
 * "render" block, then the command line. */
typedef struct pf_settings {
    int width, height;
    int spp;                   /* camera samples per pixel */
    uint64_t photons;          /* global photons emitted */
    uint64_t caustic_photons;  /* caustic photons emitted */
    int gather;                /* final-gather rays per camera sample at a diffuse hit */
    int gather_filter;         /* first gathers shared over (2n+1)^2 pixels; 0: none */
    int light_samples;         /* shadow rays per area-light sample at a diffuse hit */
    int max_depth;             /* specular recursion depth (camera side) */
    int photon_max_depth;      /* bounces a photon may make */
    int global_k;              /* photons in a global-map (irradiance) estimate */
    int caustic_k;             /* photons in a caustic estimate */
    float caustic_radius;      /* max caustic search radius, world units; 0: automatic */
    float global_radius;       /* max global search radius, world units; 0: automatic */
    int irradiance_stride;     /* precompute irradiance at every n-th global photon */
    int threads;               /* 0: all cores */
    uint64_t seed;
    float exposure;            /* stops, for the PNG only */
    /* The progressive pass this is (0: the first, or the only one). A pass
     * draws its own photons and camera samples (its seed is
     * pf_pass_seed(seed, pass), set by whoever plans the passes) and its
     * photon estimates average over a disc shrunk by pf_pass_shrink2(pass)
     * (photon/photonmap.h). */
    int pass;
    /* The pixel filter: a box filter_box pixels wide convolved with a tent
     * of radius filter_tent pixels (box 1, tent 0: each pixel averages the
     * light over its own square; box 0, tent 1: pbrt's "triangle" filter of
     * radius 1; box 1, tent 0.5: a tent of radius 1 at twice the size,
     * box-downsampled by 2). Camera samples are drawn from the filter, each
     * with weight one for its pixel (filter importance sampling). */
    float filter_box, filter_tent;
    /* The most scattering events (specular ones included) of a light path
     * from the light to the camera, pbrt's Integrator "maxdepth": 0, no
     * limit; -1, none (only emitters seen directly; pbrt's maxdepth 0).
     * Photons carry their bounce counts and the estimates take only those
     * whose path fits (render/render.c, photon/photonmap.h). */
    int path_max_depth;
} pf_settings_t;

/* The bounces a photon is traced for: photon_max_depth, and no more than
 * path_max_depth (a photon stored after D bounces has a path of D + 1
 * events at the least, which no estimate takes). */
static inline int pf_photon_depth(const pf_settings_t *s)
{
    return s->path_max_depth > 0 && s->path_max_depth < s->photon_max_depth ? s->path_max_depth
                                                                            : s->photon_max_depth;
}

/* The most photon bounces a final gather from the camera's first vertex
 * may read (the precomputed irradiance holds those): pf_pm_bounce_limit's
 * limit for depth limit d = settings.path_max_depth; 0 (all) without one. */
static inline unsigned pf_gather_bounce_limit(const pf_settings_t *s)
{
    /* camera vertex 1 and the gather's vertex 2 are two of the events */
    if (s->path_max_depth <= 0)
        return 0;
    int allowed = s->path_max_depth - 2;
    return allowed >= 255 ? 0u : allowed < 0 ? 1u : (unsigned)allowed + 1u;
}

/* The widest box and tent of the pixel filter, in pixels. */
#define PF_MAX_FILTER_WIDTH 4.0f

/* Reads a pixel filter: "box" (box 1), "box:W", "tent" (radius 1),
 * "tent:R", or a box and a tent joined by '+' ("box+tent:0.5"); widths in
 * pixels, within 0..PF_MAX_FILTER_WIDTH, not both zero. 0 with *box and
 * *tent set, or PF_EINVAL (neither touched). */
int pf_pixel_filter_parse(const char *spec, float *box, float *tent);

pf_settings_t pf_settings_default(void);

/* The seed of progressive pass `pass` of a render seeded `seed`: the seed
 * itself for pass 0 (so a one-pass render is the render without passes), a
 * hash of both for the others, so every pass draws independent photons and
 * camera samples. */
uint64_t pf_pass_seed(uint64_t seed, int pass);

typedef struct pf_scene {
    char path[1024];          /* the file it was loaded from */
    pf_material_t *mats;
    size_t nmats, cap_mats;
    pf_mesh_t *meshes;
    size_t nmeshes, cap_meshes;
    pf_sphere_t *spheres;
    size_t nspheres, cap_spheres;
    pf_light_t *lights;
    size_t nlights, cap_lights;
    pf_texture_t *texs;       /* the textures materials refer to (scene/texture.h) */
    size_t ntexs, cap_texs;
    pf_envmap_t *envmaps;     /* the images of image-based infinite lights */
    size_t nenvmaps, cap_envmaps;
    pf_camera_desc_t camera;
    int has_camera;
    pf_settings_t settings;
} pf_scene_t;

/* Creates an empty scene with default settings; NULL when out of memory. */
pf_scene_t *pf_scene_create(void);
/* Frees the scene and everything it owns; NULL-safe; sets *self_p = NULL. */
void pf_scene_destroy(pf_scene_t **self_p);

/* Appends a material and returns its index (>= 0) or PF_ENOMEM. */
int pf_scene_add_material(pf_scene_t *self, const pf_material_t *mat);
/* Index of the material named name, or -1. */
int pf_scene_find_material(const pf_scene_t *self, const char *name);
/* Appends a mesh, taking ownership of its arrays (and zeroing *mesh). 0 or PF_ENOMEM. */
int pf_scene_add_mesh(pf_scene_t *self, pf_mesh_t *mesh);
int pf_scene_add_sphere(pf_scene_t *self, const pf_sphere_t *sphere);
int pf_scene_add_light(pf_scene_t *self, const pf_light_t *light);
/* Appends an environment image, taking ownership of its pixels (and zeroing
 * *map); returns its index (>= 0) or PF_ENOMEM. */
int pf_scene_add_envmap(pf_scene_t *self, pf_envmap_t *map);
/* Frees a mesh's arrays (for meshes not handed to a scene). */
void pf_mesh_free(pf_mesh_t *mesh);

/* Frees a texture's pixels (for textures not handed to a scene). */
void pf_texture_free(pf_texture_t *tex);

/* A default material: grey Lambertian (kd 0.8). */
pf_material_t pf_material_default(const char *name);

/* Checks the scene (indices in range, finite values, at least one light) and
 * drops degenerate triangles with one warning line. Frames a camera around the
 * geometry if none was given. 0 or a status with err filled. */
int pf_scene_finalize(pf_scene_t *self, pf_error_t *err);

/* World-space bounds of all geometry and of the point and spot lights
 * (distant and infinite lights have no position). */
void pf_scene_bounds(const pf_scene_t *self, pf_vec3 *lo, pf_vec3 *hi);
/* The bounds of the geometry alone (meshes and spheres, not the lights);
 * lo > hi when there is none. */
void pf_scene_geometry_bounds(const pf_scene_t *self, pf_vec3 *lo, pf_vec3 *hi);

#endif
