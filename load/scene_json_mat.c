/* scene_json_mat.c: the JSON reader's material kinds made of others or
 * passing light through (docs/scene-format.md):
 *   { "type": "diffusetransmission", "kd": reflectance (default 0.25),
 *     "kt": transmittance (default 0.25), "emission" } - kd + kt <= 1 per
 *     channel (pbrt-v4's diffusetransmission; material/difftrans.h);
 *   { "type": "mix", "materials": [ "a", "b" ], "amount": p in [0, 1]
 *     (default 0.5), "emission" } - at each hit "b" with probability p,
 *     else "a" (pbrt-v4's mix); both named materials defined earlier in
 *     this file (so mixes cannot form cycles);
 *   on every kind, "twosided": true with an "emission": the emission leaves
 *     both sides of its triangles (pbrt-v4's two-sided area light).
 * Called by scene_json.c's material reader, on the loading thread. */
#include <string.h>

#include "load/json_ctx.h"

static const char *const s_difftrans_keys[] = { "kd", "kt", "emission", NULL };
static const char *const s_mix_keys[] = { "materials", "amount", "emission", NULL };

int pf_json_material_kind(const char *type, pf_material_t *mat, const char *const **valid)
{
    if (strcmp(type, "diffusetransmission") == 0) {
        mat->type = PF_MAT_DIFFUSE_TRANSMISSION;
        mat->kd = mat->kt = pf_v3s(0.25f); /* pbrt-v4's defaults */
        *valid = s_difftrans_keys;
        return 1;
    }
    if (strcmp(type, "mix") == 0) {
        mat->type = PF_MAT_MIX;
        mat->kd = pf_v3s(0.0f);
        mat->amount = 0.5f;
        *valid = s_mix_keys;
        return 1;
    }
    return 0;
}

/* The index of this file's material named name, or -1. */
static int s_find(const s_ctx_t *c, const char *name)
{
    for (size_t i = c->mat_base; i < c->mat_end; i++)
        if (strcmp(c->scene->mats[i].name, name) == 0)
            return (int)i;
    return -1;
}

static int s_mix(s_ctx_t *c, const cJSON *m, pf_material_t *mat)
{
    const char *what = "material";
    const cJSON *v;
    int rc = pf_json_require(c, m, "materials", what, &v);
    if (rc)
        return rc;
    if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != 2)
        return S_FAIL_AT(c, v, "material '%s': 'materials' must be an array of two material names", mat->name);
    for (int k = 0; k < 2; k++) {
        const cJSON *e = cJSON_GetArrayItem(v, k);
        const char *name;
        if ((rc = pf_json_string(c, e, "materials", what, &name)))
            return rc;
        int idx = s_find(c, name);
        if (idx < 0)
            return S_FAIL_AT(c, e, "material '%s': no material named '%s' before it", mat->name, name);
        mat->mix[k] = (uint32_t)idx;
    }
    if ((v = pf_json_get(m, "amount"))) {
        if ((rc = pf_json_float(c, v, "amount", what, &mat->amount)))
            return rc;
        if (!(mat->amount >= 0.0f && mat->amount <= 1.0f))
            return S_FAIL_AT(c, v, "'amount' in material must lie in [0, 1] (got %g)", mat->amount);
    }
    return PF_OK;
}

/* "twosided": a boolean, true only beside an emission. */
static int s_twosided(s_ctx_t *c, const cJSON *m, pf_material_t *mat)
{
    const cJSON *v = pf_json_get(m, "twosided");
    if (!v)
        return PF_OK;
    if (!cJSON_IsBool(v))
        return S_FAIL_AT(c, v, "'twosided' in material must be true or false, not %s", pf_json_type_name(v));
    mat->twosided = cJSON_IsTrue(v) ? 1u : 0u;
    if (mat->twosided && pf_is_black(mat->le))
        return S_FAIL_AT(c, v, "material '%s': 'twosided' needs an 'emission' (it says which sides emit)", mat->name);
    return PF_OK;
}

int pf_json_material_more(s_ctx_t *c, const cJSON *m, pf_material_t *mat)
{
    int rc = s_twosided(c, m, mat);
    if (rc)
        return rc;
    if (mat->type == PF_MAT_MIX)
        return s_mix(c, m, mat);
    if (mat->type == PF_MAT_DIFFUSE_TRANSMISSION)
        for (int k = 0; k < 3; k++)
            if (pf_vget(mat->kd, k) + pf_vget(mat->kt, k) > 1.0f + 1e-6f)
                return S_FAIL_AT(c, m, "material '%s': kd + kt exceeds 1 in channel %d (it would create energy)",
                                 mat->name, k);
    return PF_OK;
}
