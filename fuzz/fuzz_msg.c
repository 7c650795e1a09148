/* fuzz_msg.c: libFuzzer target for every wire message decoder. The input is
 * one frame as it arrives from a ROUTER or DEALER socket; pf_msg_decode
 * dispatches on the type field of the header, and the seed corpus holds one
 * frame of every type (make_corpus), so each decoder is reached from the
 * first run on.
 *
 * Oracles, for a frame that decodes: the message passes the checks its
 * receiver makes next (a HELLO's fingerprint check runs, a JOB's settings
 * are in range), a RESULT's pixels copy out finite and >= 0, and encoding
 * the message gives back the frame byte for byte. The last one catches a
 * decoder that accepts what the encoder would refuse or reads a field
 * differently from how it is written.
 *
 * One thread; the regression driver and libFuzzer call it in a loop. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "base/wire.h"
#include "fuzz/fuzz_util.h"
#include "proto/messages.h"
#include "render/frame.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    pf_msg_t msg;
    char why[256];
    int rc = pf_msg_decode(data, size, &msg, why, sizeof why);
    if (rc != PF_OK) {
        PF_FUZZ_REQUIRE(rc == PF_EPARSE || rc == PF_EMISMATCH, "pf_msg_decode returned %d", rc);
        PF_FUZZ_REQUIRE(why[0] != '\0', "a refused frame has no reason");
        return 0;
    }
    PF_FUZZ_REQUIRE(msg.type >= 1 && msg.type <= PF_MSG_MAX_TYPE, "decoded type %d", (int)msg.type);
    PF_FUZZ_REQUIRE(strcmp(pf_msg_type_name(msg.type), "UNKNOWN") != 0, "type %d has no name", (int)msg.type);

    float *pixels = NULL;
    pf_msg_photon_t *photons = NULL;
    uint64_t *leaves = NULL;
    switch (msg.type) {
    case PF_MSG_HELLO: {
        pf_fingerprint_t self = pf_frame_fingerprint();
        char text[512];
        rc = pf_fingerprint_check(&msg.u.hello.fp, &self, text, sizeof text);
        PF_FUZZ_REQUIRE(rc == PF_OK || (rc == PF_EMISMATCH && text[0]), "fingerprint check returned %d", rc);
        break;
    }
    case PF_MSG_JOB: {
        char text[256];
        PF_FUZZ_REQUIRE(pf_settings_check(&msg.u.job.settings, text, sizeof text) == PF_OK,
                        "a decoded JOB has settings out of range: %s", text);
        break;
    }
    case PF_MSG_RESULT: {
        size_t n = (size_t)msg.u.result.w * msg.u.result.h * 3;
        pixels = malloc(n * sizeof *pixels);
        PF_FUZZ_REQUIRE(pixels != NULL, "out of memory");
        pf_msg_result_pixels(&msg.u.result, pixels);
        for (size_t i = 0; i < n; i++)
            PF_FUZZ_REQUIRE(isfinite(pixels[i]) && pixels[i] >= 0.0f, "pixel value %g", (double)pixels[i]);
        msg.u.result.rgb = pixels;
        break;
    }
    case PF_MSG_PHOTON_REQ: {
        char text[256];
        PF_FUZZ_REQUIRE(pf_settings_check(&msg.u.photon_req.settings, text, sizeof text) == PF_OK,
                        "a decoded PHOTON_REQ has settings out of range: %s", text);
        PF_FUZZ_REQUIRE(msg.u.photon_req.count >= 1 &&
                            (uint64_t)msg.u.photon_req.first + msg.u.photon_req.count <= PF_PROTO_MAX_BATCHES,
                        "PHOTON_REQ range %u+%u", msg.u.photon_req.first, msg.u.photon_req.count);
        break;
    }
    case PF_MSG_IRR_REQ: {
        char text[256];
        PF_FUZZ_REQUIRE(pf_settings_check(&msg.u.irr_req.settings, text, sizeof text) == PF_OK,
                        "a decoded IRR_REQ has settings out of range: %s", text);
        PF_FUZZ_REQUIRE(msg.u.irr_req.count >= 1 && msg.u.irr_req.maps_size >= 1 &&
                            (uint64_t)msg.u.irr_req.first + msg.u.irr_req.count <= PF_PROTO_MAX_IRR_CHUNKS,
                        "IRR_REQ range %u+%u", msg.u.irr_req.first, msg.u.irr_req.count);
        break;
    }
    case PF_MSG_PHOTONS:
    case PF_MSG_IRR_POINTS: {
        const pf_msg_photons_t *p = &msg.u.photons;
        PF_FUZZ_REQUIRE(p->first + p->n <= p->total && p->indirect <= p->total, "PHOTONS counts");
        photons = malloc((p->n + 1) * sizeof *photons);
        PF_FUZZ_REQUIRE(photons != NULL, "out of memory");
        for (uint32_t i = 0; i < p->n; i++) {
            pf_msg_photon_get(p, i, &photons[i]);
            for (int c = 0; c < 3; c++)
                PF_FUZZ_REQUIRE(isfinite(photons[i].pos[c]) && isfinite(photons[i].power[c]) &&
                                    photons[i].power[c] >= 0.0f,
                                "photon %u", i);
        }
        msg.u.photons.photons = photons;
        break;
    }
    case PF_MSG_BLOB_PLAN: {
        const pf_msg_blob_plan_t *p = &msg.u.plan;
        PF_FUZZ_REQUIRE(p->size >= 1 && p->n >= 1 && p->n <= PF_PROTO_MAX_PLAN_CHUNKS, "BLOB_PLAN counts");
        leaves = malloc((size_t)p->n * sizeof *leaves);
        PF_FUZZ_REQUIRE(leaves != NULL, "out of memory");
        for (uint32_t k = 0; k < p->n; k++)
            leaves[k] = pf_msg_plan_leaf(p, k);
        msg.u.plan.leaves = leaves;
        break;
    }
    default:
        break;
    }

    pf_buf_t out = { 0 };
    rc = pf_msg_encode(&msg, &out);
    PF_FUZZ_REQUIRE(rc == PF_OK, "a decoded %s does not encode: %s", pf_msg_type_name(msg.type), pf_strerror(rc));
    PF_FUZZ_REQUIRE(out.len == size && memcmp(out.data, data, size) == 0,
                    "%s: decode then encode gives %zu bytes, not the %zu of the frame", pf_msg_type_name(msg.type),
                    out.len, size);
    pf_buf_free(&out);
    free(pixels);
    free(photons);
    free(leaves);
    return 0;
}
