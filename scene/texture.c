/* texture.c: the scene's texture table and its evaluation (texture.h).
 * Images are looked up bilinearly at pbrt-v4's pixel centres (x = s w -
 * 1/2, y = (1 - t) h - 1/2: t runs up from the bottom row, the rows are
 * stored top first) without mip-mapping; the wrap mode says what lies
 * outside [0, 1)^2. 8-bit sRGB pixels decode through a table of the exact
 * curve, so an image costs 3 bytes a pixel in memory and in the scene blob.
 * Procedural operands refer only to earlier textures (checked), so
 * evaluation recurses at most ntexs deep and always ends. */
#include "scene/texture.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/reserve.h"

static const float s_srgb[256] = {
    0.000000000e+00f, 3.035269835e-04f, 6.070539671e-04f, 9.105809506e-04f, 1.214107934e-03f, 1.517634918e-03f,
    1.821161901e-03f, 2.124688885e-03f, 2.428215868e-03f, 2.731742852e-03f, 3.035269835e-03f, 3.346535764e-03f,
    3.676507324e-03f, 4.024717018e-03f, 4.391442037e-03f, 4.776953481e-03f, 5.181516702e-03f, 5.605391624e-03f,
    6.048833023e-03f, 6.512090793e-03f, 6.995410187e-03f, 7.499032043e-03f, 8.023192985e-03f, 8.568125618e-03f,
    9.134058702e-03f, 9.721217320e-03f, 1.032982303e-02f, 1.096009401e-02f, 1.161224518e-02f, 1.228648836e-02f,
    1.298303234e-02f, 1.370208305e-02f, 1.444384360e-02f, 1.520851442e-02f, 1.599629337e-02f, 1.680737575e-02f,
    1.764195449e-02f, 1.850022013e-02f, 1.938236096e-02f, 2.028856306e-02f, 2.121901038e-02f, 2.217388479e-02f,
    2.315336618e-02f, 2.415763245e-02f, 2.518685963e-02f, 2.624122189e-02f, 2.732089164e-02f, 2.842603950e-02f,
    2.955683444e-02f, 3.071344373e-02f, 3.189603307e-02f, 3.310476657e-02f, 3.433980681e-02f, 3.560131488e-02f,
    3.688945040e-02f, 3.820437160e-02f, 3.954623528e-02f, 4.091519691e-02f, 4.231141062e-02f, 4.373502926e-02f,
    4.518620439e-02f, 4.666508634e-02f, 4.817182423e-02f, 4.970656598e-02f, 5.126945837e-02f, 5.286064702e-02f,
    5.448027644e-02f, 5.612849005e-02f, 5.780543019e-02f, 5.951123816e-02f, 6.124605423e-02f, 6.301001765e-02f,
    6.480326669e-02f, 6.662593864e-02f, 6.847816984e-02f, 7.036009570e-02f, 7.227185068e-02f, 7.421356838e-02f,
    7.618538148e-02f, 7.818742181e-02f, 8.021982031e-02f, 8.228270713e-02f, 8.437621154e-02f, 8.650046204e-02f,
    8.865558629e-02f, 9.084171118e-02f, 9.305896285e-02f, 9.530746663e-02f, 9.758734714e-02f, 9.989872825e-02f,
    1.022417331e-01f, 1.046164841e-01f, 1.070231030e-01f, 1.094617108e-01f, 1.119324278e-01f, 1.144353738e-01f,
    1.169706678e-01f, 1.195384280e-01f, 1.221387722e-01f, 1.247718176e-01f, 1.274376804e-01f, 1.301364767e-01f,
    1.328683216e-01f, 1.356333297e-01f, 1.384316150e-01f, 1.412632911e-01f, 1.441284709e-01f, 1.470272665e-01f,
    1.499597898e-01f, 1.529261520e-01f, 1.559264637e-01f, 1.589608351e-01f, 1.620293756e-01f, 1.651321945e-01f,
    1.682694002e-01f, 1.714411007e-01f, 1.746474037e-01f, 1.778884160e-01f, 1.811642442e-01f, 1.844749945e-01f,
    1.878207723e-01f, 1.912016827e-01f, 1.946178304e-01f, 1.980693196e-01f, 2.015562538e-01f, 2.050787364e-01f,
    2.086368701e-01f, 2.122307574e-01f, 2.158605001e-01f, 2.195261997e-01f, 2.232279573e-01f, 2.269658735e-01f,
    2.307400485e-01f, 2.345505822e-01f, 2.383975738e-01f, 2.422811225e-01f, 2.462013267e-01f, 2.501582847e-01f,
    2.541520943e-01f, 2.581828529e-01f, 2.622506575e-01f, 2.663556048e-01f, 2.704977910e-01f, 2.746773121e-01f,
    2.788942635e-01f, 2.831487404e-01f, 2.874408377e-01f, 2.917706498e-01f, 2.961382708e-01f, 3.005437944e-01f,
    3.049873141e-01f, 3.094689228e-01f, 3.139887134e-01f, 3.185467781e-01f, 3.231432091e-01f, 3.277780981e-01f,
    3.324515363e-01f, 3.371636150e-01f, 3.419144249e-01f, 3.467040564e-01f, 3.515325995e-01f, 3.564001441e-01f,
    3.613067798e-01f, 3.662525956e-01f, 3.712376805e-01f, 3.762621230e-01f, 3.813260114e-01f, 3.864294338e-01f,
    3.915724777e-01f, 3.967552307e-01f, 4.019777798e-01f, 4.072402119e-01f, 4.125426135e-01f, 4.178850708e-01f,
    4.232676700e-01f, 4.286904966e-01f, 4.341536362e-01f, 4.396571738e-01f, 4.452011945e-01f, 4.507857828e-01f,
    4.564110232e-01f, 4.620769997e-01f, 4.677837961e-01f, 4.735314961e-01f, 4.793201831e-01f, 4.851499401e-01f,
    4.910208498e-01f, 4.969329951e-01f, 5.028864580e-01f, 5.088813209e-01f, 5.149176654e-01f, 5.209955732e-01f,
    5.271151257e-01f, 5.332764040e-01f, 5.394794890e-01f, 5.457244614e-01f, 5.520114015e-01f, 5.583403896e-01f,
    5.647115057e-01f, 5.711248295e-01f, 5.775804404e-01f, 5.840784179e-01f, 5.906188409e-01f, 5.972017884e-01f,
    6.038273389e-01f, 6.104955708e-01f, 6.172065624e-01f, 6.239603917e-01f, 6.307571363e-01f, 6.375968740e-01f,
    6.444796820e-01f, 6.514056374e-01f, 6.583748173e-01f, 6.653872983e-01f, 6.724431570e-01f, 6.795424696e-01f,
    6.866853124e-01f, 6.938717613e-01f, 7.011018919e-01f, 7.083757799e-01f, 7.156935005e-01f, 7.230551289e-01f,
    7.304607401e-01f, 7.379104088e-01f, 7.454042095e-01f, 7.529422168e-01f, 7.605245047e-01f, 7.681511472e-01f,
    7.758222183e-01f, 7.835377915e-01f, 7.912979403e-01f, 7.991027380e-01f, 8.069522577e-01f, 8.148465722e-01f,
    8.227857544e-01f, 8.307698768e-01f, 8.387990117e-01f, 8.468732315e-01f, 8.549926081e-01f, 8.631572135e-01f,
    8.713671192e-01f, 8.796223969e-01f, 8.879231179e-01f, 8.962693534e-01f, 9.046611744e-01f, 9.130986518e-01f,
    9.215818563e-01f, 9.301108584e-01f, 9.386857285e-01f, 9.473065367e-01f, 9.559733532e-01f, 9.646862479e-01f,
    9.734452904e-01f, 9.822505503e-01f, 9.911020971e-01f, 1.000000000e+00f,
};

float pf_srgb8_to_linear(uint8_t i) { return s_srgb[i]; }

pf_texture_t pf_texture_constant(const char *name, pf_vec3 c)
{
    pf_texture_t t;
    memset(&t, 0, sizeof t);
    snprintf(t.name, sizeof t.name, "%s", name ? name : "");
    t.type = PF_TEX_CONSTANT;
    t.su = t.sv = 1.0f;
    t.scale = 1.0f;
    t.op[0].c = c;
    return t;
}

int pf_scene_add_texture(pf_scene_t *self, pf_texture_t *tex)
{
    if (self->ntexs >= UINT32_MAX - 1 ||
        pf_reserve((void **)&self->texs, &self->cap_texs, self->ntexs + 1, sizeof *tex))
        return PF_ENOMEM;
    self->texs[self->ntexs] = *tex;
    memset(tex, 0, sizeof *tex);
    return (int)++self->ntexs;
}

size_t pf_textures_bytes(const pf_scene_t *self)
{
    size_t b = 0;
    for (size_t i = 0; i < self->ntexs; i++) {
        const pf_texture_t *t = &self->texs[i];
        size_t n = (size_t)t->width * (size_t)t->height * 3;
        b += t->px8 ? n : t->pxf ? n * sizeof(float) : 0;
    }
    return b;
}

void pf_mesh_uv(const pf_mesh_t *m, size_t tri, float b1, float b2, float uv[2])
{
    float b0 = 1.0f - b1 - b2;
    if (!m->uv) {
        /* pbrt-v4's Triangle without uv: corners (0,0), (1,0), (1,1). */
        uv[0] = b1 + b2;
        uv[1] = b2;
        return;
    }
    const uint32_t *v = &m->idx[3 * tri];
    const float *a = &m->uv[2 * v[0]], *b = &m->uv[2 * v[1]], *c = &m->uv[2 * v[2]];
    uv[0] = b0 * a[0] + b1 * b[0] + b2 * c[0];
    uv[1] = b0 * a[1] + b1 * b[1] + b2 * c[1];
}

/* Pixel (x, y) of an image texture (y from the top), through its wrap mode. */
static pf_vec3 s_texel(const pf_texture_t *t, int x, int y)
{
    int w = t->width, h = t->height;
    if (x < 0 || x >= w || y < 0 || y >= h) {
        if (t->wrap == PF_WRAP_BLACK)
            return pf_v3s(0.0f);
        if (t->wrap == PF_WRAP_CLAMP) {
            x = x < 0 ? 0 : x >= w ? w - 1 : x;
            y = y < 0 ? 0 : y >= h ? h - 1 : y;
        } else {
            x %= w;
            y %= h;
            x += x < 0 ? w : 0;
            y += y < 0 ? h : 0;
        }
    }
    size_t i = 3 * ((size_t)y * (size_t)w + (size_t)x);
    if (t->pxf)
        return pf_v3(t->pxf[i], t->pxf[i + 1], t->pxf[i + 2]);
    const uint8_t *p = &t->px8[i];
    if (t->srgb)
        return pf_v3(s_srgb[p[0]], s_srgb[p[1]], s_srgb[p[2]]);
    return pf_v3(p[0] / 255.0f, p[1] / 255.0f, p[2] / 255.0f);
}

/* A coordinate's pixel and weight, kept in int range for any float. */
static int s_split(float x, float *f)
{
    if (!(x > -1e9f))
        x = -1e9f;
    if (x > 1e9f)
        x = 1e9f;
    float x0 = floorf(x);
    *f = x - x0;
    return (int)x0;
}

static pf_vec3 s_image(const pf_texture_t *t, float s, float tt)
{
    float fx, fy;
    int x = s_split(s * (float)t->width - 0.5f, &fx);
    int y = s_split((1.0f - tt) * (float)t->height - 0.5f, &fy);
    pf_vec3 a = pf_add(pf_scale(s_texel(t, x, y), 1.0f - fx), pf_scale(s_texel(t, x + 1, y), fx));
    pf_vec3 b = pf_add(pf_scale(s_texel(t, x, y + 1), 1.0f - fx), pf_scale(s_texel(t, x + 1, y + 1), fx));
    pf_vec3 v = pf_scale(pf_add(pf_scale(a, 1.0f - fy), pf_scale(b, fy)), t->scale);
    if (t->invert)
        v = pf_vmax(pf_sub(pf_v3s(1.0f), v), pf_v3s(0.0f));
    return v;
}

static pf_vec3 s_operand(const pf_scene_t *scene, const pf_tex_operand_t *op, float u, float v)
{
    return op->ref ? pf_texture_eval(scene, op->ref, u, v) : op->c;
}

pf_vec3 pf_texture_eval(const pf_scene_t *scene, uint32_t ref, float u, float v)
{
    const pf_texture_t *t = &scene->texs[ref - 1];
    float s = t->su * u + t->du, tt = t->sv * v + t->dv;
    switch (t->type) {
    case PF_TEX_IMAGE:
        return s_image(t, s, tt);
    case PF_TEX_CHECKER: {
        float fs, ft;
        int even = ((s_split(s, &fs) + s_split(tt, &ft)) & 1) == 0;
        return s_operand(scene, &t->op[even ? 0 : 1], u, v);
    }
    case PF_TEX_SCALE:
        return pf_mul(s_operand(scene, &t->op[0], u, v), s_operand(scene, &t->op[1], u, v));
    case PF_TEX_MIX: {
        float a = s_operand(scene, &t->op[2], u, v).x;
        pf_vec3 x = s_operand(scene, &t->op[0], u, v), y = s_operand(scene, &t->op[1], u, v);
        return pf_add(pf_scale(x, 1.0f - a), pf_scale(y, a));
    }
    default:
        return t->op[0].c;
    }
}
