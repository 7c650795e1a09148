# The wire protocol's codecs: the cursor, every message type (round trips,
# truncations, corruptions, random frames) and the handshake fingerprint.
pf_add_test(proto ${CMAKE_CURRENT_LIST_DIR}/test_proto.c LIBS pf_proto LABELS unit)

# The scene blob and the photon-map blob: round trips, truncations, hostile
# counts and corrupted fields.
pf_add_test(blobs ${CMAKE_CURRENT_LIST_DIR}/test_blobs.c LIBS pf_proto LABELS unit)
