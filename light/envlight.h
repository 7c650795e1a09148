/* envlight.h: private to light/. An image-based infinite light's sampling
 * distribution (envlight.c): a 2D piecewise-constant distribution over the
 * map's pixels, each weighted by its mean channel (times the light's scale)
 * and its solid angle, so that a pixel's directions are drawn with a
 * solid-angle pdf proportional to the pixel's value: pdf(d) = mean(L(d)) /
 * total. Built once, read-only after. */
#ifndef PF_ENVLIGHT_H
#define PF_ENVLIGHT_H

#include <stdint.h>

#include "scene/envmap.h"

typedef struct pf_envlight {
    const pf_envmap_t *map; /* the scene's */
    pf_vec3 scale;          /* the light's intensity */
    float *marg;            /* height + 1: the rows' cdf */
    float *cond;            /* height x (width + 1): each row's cdf over its pixels */
    double total;           /* sum over pixels of mean(scale * pixel) * solid angle */
    double lum;             /* the integral over the sphere of lum(L): the light's power is pi R^2 lum */
    float pmf;              /* the light table's probability of this entry (set by light.c) */
    /* Guide tables (lighttab.h) over marg (marg_bits) and over each row of
     * cond (cond_bits, 2^cond_bits + 1 entries a row); NULL: bisect all. */
    uint32_t *marg_guide, *cond_guide;
    unsigned marg_bits, cond_bits;
} pf_envlight_t;

/* Builds the distribution; PF_ENOMEM. A black map gets total 0 (samples nothing). */
int pf_envlight_init(pf_envlight_t *e, const pf_envmap_t *map, pf_vec3 scale);
void pf_envlight_free(pf_envlight_t *e);
/* The radiance seen along a world direction d (towards the sky). */
pf_vec3 pf_envlight_le(const pf_envlight_t *e, pf_vec3 d);
/* A direction towards the sky drawn from the distribution (u in [0, 1)^2). */
pf_vec3 pf_envlight_sample(const pf_envlight_t *e, float u1, float u2);
/* The solid-angle pdf with which pf_envlight_sample returns d. */
float pf_envlight_pdf(const pf_envlight_t *e, pf_vec3 d);
/* The same from le = pf_envlight_le(e, d), bit for bit. */
float pf_envlight_pdf_le(const pf_envlight_t *e, pf_vec3 le);

#endif
