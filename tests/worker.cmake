# The worker side of the farm (tests/test_worker.c): key files (unit), and a
# real photonfarm-worker process against a scripted coordinator in the test
# (integration): handshake, blob transfer and cache, bit-identical tiles,
# garbage frames, reconnection, signals, REFUSE, CURVE admission.
pf_add_test(worker_protocol test_worker.c LIBS pf_coordinator pf_proto pf_common PkgConfig::ZMQ
            ARGS protocol $<TARGET_FILE:photonfarm-worker> LABELS integration)
add_dependencies(test_worker_protocol photonfarm-worker)
set_tests_properties(worker_protocol PROPERTIES TIMEOUT 120)
add_test(NAME keyfile COMMAND test_worker_protocol keyfile WORKING_DIRECTORY ${CMAKE_SOURCE_DIR})
set_tests_properties(keyfile PROPERTIES LABELS unit)
