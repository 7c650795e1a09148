/* bench_transfer.c: photon-map transfer over loopback, as the farm does it.
 *
 * Builds a global map of N random photons (default 5,000,000) plus small
 * caustic and irradiance maps, serializes it (pf_mapfile_write), and moves it
 * from a ZMQ_ROUTER to a ZMQ_DEALER over tcp://127.0.0.1 with the protocol's
 * BLOB_REQ / BLOB_CHUNK messages (1 MiB chunks, a credit window of 8, every
 * frame encoded and decoded by proto/messages.c), then checks the content
 * hash and validates the map (pf_mapfile_read, down to the kd-tree order).
 * Prints bytes per photon on the wire and MB/s for the transfer alone and
 * with hashing and validation.
 *
 * usage: bench_transfer [photons] */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zmq.h>

#include "base/hash.h"
#include "base/log.h"
#include "base/rng.h"
#include "photon/mapfile.h"
#include "proto/messages.h"

typedef struct {
    void *ctx;
    const pf_buf_t *blob;
    uint64_t hash;
    char endpoint[128];
    volatile int ready;
} s_server;

static void *s_serve(void *arg)
{
    s_server *sv = arg;
    void *s = zmq_socket(sv->ctx, ZMQ_ROUTER);
    zmq_bind(s, "tcp://127.0.0.1:*");
    size_t len = sizeof sv->endpoint;
    zmq_getsockopt(s, ZMQ_LAST_ENDPOINT, sv->endpoint, &len);
    __atomic_store_n(&sv->ready, 1, __ATOMIC_RELEASE);
    pf_buf_t out = { 0 };
    uint8_t id[256], frame[256];
    for (;;) {
        int il = zmq_recv(s, id, sizeof id, 0);
        int fl = zmq_recv(s, frame, sizeof frame, 0);
        pf_msg_t m;
        char why[128];
        if (il < 0 || fl < 0 || pf_msg_decode(frame, (size_t)fl, &m, why, sizeof why) != PF_OK)
            break;
        if (m.type == PF_MSG_BYE)
            break;
        uint64_t off = m.u.blob_req.offset;
        for (uint32_t c = 0; c < m.u.blob_req.credit && off < sv->blob->len; c++) {
            uint64_t n = sv->blob->len - off < PF_PROTO_CHUNK_SIZE ? sv->blob->len - off : PF_PROTO_CHUNK_SIZE;
            pf_msg_t ch = { .type = PF_MSG_BLOB_CHUNK, .job = 1 };
            ch.u.chunk = (pf_msg_blob_chunk_t){ sv->hash, sv->blob->len, off, (uint32_t)n, sv->blob->data + off };
            pf_msg_encode(&ch, &out);
            zmq_send(s, id, (size_t)il, ZMQ_SNDMORE);
            zmq_send(s, out.data, out.len, 0);
            off += n;
        }
    }
    pf_buf_free(&out);
    zmq_close(s);
    return NULL;
}

static pf_kdtree_t *s_random_tree(size_t n, uint64_t seed)
{
    pf_photon_t *p = malloc((n ? n : 1) * sizeof *p);
    for (size_t i = 0; i < n; i++) {
        pf_rng_t r = pf_rng_make(seed, PF_STREAM_TEST, i, 0);
        p[i] = (pf_photon_t){ { pf_rng_float(&r), pf_rng_float(&r), pf_rng_float(&r) },
                              { 1e-6f, 2e-6f, 3e-6f }, pf_oct_encode(pf_v3(0, -1, 0)), pf_oct_encode(pf_v3(0, 1, 0)) };
    }
    return pf_kdtree_build(&p, n);
}

int main(int argc, char **argv)
{
    size_t n = argc > 1 ? strtoull(argv[1], NULL, 10) : 5000000;
    pf_photon_maps_t maps = { 0 };
    maps.global = s_random_tree(n, 1);
    maps.caustic = s_random_tree(1000, 2);
    maps.irradiance = s_random_tree(1000, 3);
    maps.global_emitted = maps.caustic_emitted = n;
    maps.global_r2 = maps.caustic_r2 = maps.irradiance_r2 = 0.01f;
    pf_buf_t blob = { 0 };
    double t0 = pf_now();
    if (pf_mapfile_write(&maps, 1, 2, &blob) != PF_OK) {
        fprintf(stderr, "serialize failed\n");
        return 1;
    }
    double t_ser = pf_now() - t0;
    uint64_t hash = pf_hash_bytes(PF_HASH_INIT, blob.data, blob.len);

    s_server sv = { zmq_ctx_new(), &blob, hash, "", 0 };
    pthread_t th;
    pthread_create(&th, NULL, s_serve, &sv);
    while (!__atomic_load_n(&sv.ready, __ATOMIC_ACQUIRE))
        ;
    void *d = zmq_socket(sv.ctx, ZMQ_DEALER);
    zmq_connect(d, sv.endpoint);
    uint8_t *dst = malloc(blob.len);
    pf_buf_t out = { 0 };
    zmq_msg_t msg;
    zmq_msg_init(&msg);
    const uint32_t window = 8;
    uint64_t requested = 0, received = 0;
    double t1 = pf_now();
    while (received < blob.len) {
        while (requested < blob.len && requested - received < (uint64_t)window / 2 * PF_PROTO_CHUNK_SIZE) {
            pf_msg_t rq = { .type = PF_MSG_BLOB_REQ, .job = 1 };
            rq.u.blob_req = (pf_msg_blob_req_t){ hash, requested, window / 2 };
            pf_msg_encode(&rq, &out);
            zmq_send(d, out.data, out.len, 0);
            requested += (uint64_t)window / 2 * PF_PROTO_CHUNK_SIZE;
        }
        if (zmq_msg_recv(&msg, d, 0) < 0)
            break;
        pf_msg_t m;
        char why[128];
        if (pf_msg_decode(zmq_msg_data(&msg), zmq_msg_size(&msg), &m, why, sizeof why) != PF_OK) {
            fprintf(stderr, "bad chunk: %s\n", why);
            return 1;
        }
        memcpy(dst + m.u.chunk.offset, m.u.chunk.data, m.u.chunk.len);
        received += m.u.chunk.len;
    }
    double t_wire = pf_now() - t1;
    int hash_ok = pf_hash_bytes(PF_HASH_INIT, dst, blob.len) == hash;
    double t_hash = pf_now() - t1;
    pf_photon_maps_t back;
    pf_error_t err;
    int rc = pf_mapfile_read(dst, blob.len, 1, 2, &back, &err);
    double t_all = pf_now() - t1;
    pf_msg_t bye = { .type = PF_MSG_BYE, .job = 1 };
    pf_msg_encode(&bye, &out);
    zmq_send(d, out.data, out.len, 0);
    pthread_join(th, NULL);
    printf("photons           %zu global (+2000 caustic/irradiance)\n", n);
    printf("blob              %zu bytes, %.2f bytes per photon on the wire (32-byte record, split axis inside)\n", blob.len,
           (double)blob.len / (double)(n + 2000));
    printf("serialize         %.3f s\n", t_ser);
    printf("transfer          %.3f s, %.0f MB/s (loopback TCP, 1 MiB chunks, window %u)\n", t_wire,
           blob.len / t_wire / 1e6, window);
    printf("+ hash check      %.3f s, %.0f MB/s (%s)\n", t_hash, blob.len / t_hash / 1e6, hash_ok ? "ok" : "MISMATCH");
    printf("+ validate/build  %.3f s, %.0f MB/s end to end (%s)\n", t_all, blob.len / t_all / 1e6,
           rc == PF_OK ? "map valid" : err.msg);
    zmq_msg_close(&msg);
    zmq_close(d);
    zmq_ctx_term(sv.ctx);
    pf_photon_maps_free(&maps);
    if (rc == PF_OK)
        pf_photon_maps_free(&back);
    pf_buf_free(&blob);
    pf_buf_free(&out);
    free(dst);
    return hash_ok && rc == PF_OK ? 0 : 1;
}
