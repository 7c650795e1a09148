/* irr_sample.h: samples of the irradiance messages (IRR_REQ, IRR_POINTS)
 * for test_proto.c's loops over every message type (round trips, every
 * truncation, corruptions, random frames), and their comparison. */
#ifndef PF_TEST_IRR_SAMPLE_H
#define PF_TEST_IRR_SAMPLE_H

#include <string.h>

#include "proto/messages.h"

/* Fills m (type, job set) with a valid message of an irradiance type;
 * pts: 3 photon records that stay valid. */
static void s_irr_sample(int type, pf_msg_t *m, pf_msg_photon_t *pts)
{
    if (type == PF_MSG_IRR_REQ) {
        pf_msg_irr_req_t *q = &m->u.irr_req;
        q->settings = pf_settings_default();
        q->settings.width = 320;
        q->settings.height = 200;
        q->scene_hash = 0x0123456789abcdefULL;
        q->scene_size = 123456;
        q->maps_hash = 0xfedcba9876543210ULL;
        q->maps_size = 7654321;
        q->first = 1000;
        q->count = 12;
    } else if (type == PF_MSG_IRR_POINTS) {
        for (int i = 0; i < 3; i++)
            pts[i] = (pf_msg_photon_t){ { 1.0f + i, -2.0f, 1e-30f }, { 0.0f, 0.5f * i, 7.0f }, 0x3f800000u | (i ? 0x80000000u : 0),
                                        0x12345678u + i };
        m->u.photons = (pf_msg_photons_t){ 77, 3, 0, 0, 0, 3, NULL, pts };
    }
}

/* The first field in which the irradiance messages a (built) and b
 * (decoded) differ, or NULL. */
static const char *s_irr_diff(const pf_msg_t *a, const pf_msg_t *b)
{
    if (a->type == PF_MSG_IRR_REQ) {
        const pf_msg_irr_req_t *x = &a->u.irr_req, *y = &b->u.irr_req;
        if (x->scene_hash != y->scene_hash || x->scene_size != y->scene_size || x->maps_hash != y->maps_hash ||
            x->maps_size != y->maps_size || x->first != y->first || x->count != y->count)
            return "irr_req";
        return pf_settings_hash(&x->settings) != pf_settings_hash(&y->settings) ? "settings" : NULL;
    }
    if (a->type == PF_MSG_IRR_POINTS) {
        const pf_msg_photons_t *x = &a->u.photons, *y = &b->u.photons;
        if (x->batch != y->batch || x->total != y->total || x->n != y->n)
            return "irr_points header";
        for (uint32_t i = 0; i < x->n; i++) {
            pf_msg_photon_t q;
            pf_msg_photon_get(y, i, &q);
            if (memcmp(&q, &x->photons[i], sizeof q))
                return "irr point";
        }
        return NULL;
    }
    return "unknown type";
}

#endif
