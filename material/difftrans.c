/* difftrans.c: the diffuse transmission BSDF, its sampling and pdf; see
 * difftrans.h. Pure functions, any thread. */
#include "material/difftrans.h"

#include "base/sampling.h"

/* The probability of sampling reflection: pr / (pr + pt), 0 when both are zero. */
static float s_p_reflect(const pf_material_t *m)
{
    float pr = pf_maxc(m->kd), pt = pf_maxc(m->kt);
    return pr + pt > 0.0f ? pr / (pr + pt) : 0.0f;
}

pf_vec3 pf_difftrans_eval(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi)
{
    float co = pf_dot(wo, n), ci = pf_dot(wi, n);
    if (co == 0.0f || ci == 0.0f)
        return pf_v3s(0.0f);
    return pf_scale((co > 0.0f) == (ci > 0.0f) ? m->kd : m->kt, PF_INV_PI);
}

float pf_difftrans_pdf(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi)
{
    float co = pf_dot(wo, n), ci = pf_dot(wi, n);
    if (co == 0.0f || ci == 0.0f || (pf_maxc(m->kd) <= 0.0f && pf_maxc(m->kt) <= 0.0f))
        return 0.0f;
    float pr = s_p_reflect(m);
    return ((co > 0.0f) == (ci > 0.0f) ? pr : 1.0f - pr) * fabsf(ci) * PF_INV_PI;
}

int pf_difftrans_sample(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, float u0, float u1, float u2, pf_vec3 *wi,
                        pf_vec3 *weight, float *pdf)
{
    float co = pf_dot(wo, n);
    float pr_ = pf_maxc(m->kd), pt_ = pf_maxc(m->kt);
    if (co == 0.0f || !(pr_ + pt_ > 0.0f))
        return 0;
    float pr = s_p_reflect(m);
    int reflect = u0 < pr;
    /* The hemisphere wo lies in for reflection, the other for transmission. */
    pf_vec3 side = (co > 0.0f) == reflect ? n : pf_neg(n);
    pf_vec3 local = pf_sample_cosine(u1, u2);
    if (!(local.z > 0.0f))
        return 0;
    *wi = pf_to_world(local, side);
    float p = reflect ? pr : 1.0f - pr;
    *pdf = p * local.z * PF_INV_PI;
    /* f |cos| / pdf = (R or T) / p: the cosines cancel. */
    *weight = pf_scale(reflect ? m->kd : m->kt, 1.0f / p);
    return 1;
}
