# Fuzzing (docs/fuzzing.md).
#
# fuzz_regress: every fuzz target (fuzz/fuzz_*.c) without libFuzzer, fed
# every seed and every crasher kept in tests/data/fuzz/<target>/ by a small
# driver (fuzz/driver.c). Each target's entry point LLVMFuzzerTestOneInput is
# renamed pf_fuzz_<target> so that one program holds them all.
set(PF_FUZZ_REGRESS_OBJECTS)
foreach(t json obj mtl ply msg sceneblob mapfile pfm)
  add_library(pf_fuzz_regress_${t} OBJECT ${CMAKE_SOURCE_DIR}/fuzz/fuzz_${t}.c)
  target_compile_definitions(pf_fuzz_regress_${t} PRIVATE LLVMFuzzerTestOneInput=pf_fuzz_${t})
  target_link_libraries(pf_fuzz_regress_${t} PRIVATE pf_proto)
  list(APPEND PF_FUZZ_REGRESS_OBJECTS $<TARGET_OBJECTS:pf_fuzz_regress_${t}>)
endforeach()
pf_add_test(fuzz_regress ${CMAKE_SOURCE_DIR}/fuzz/driver.c ${PF_FUZZ_REGRESS_OBJECTS} LIBS pf_proto LABELS unit)

# allocfail: every decoder with a valid input, failing its N-th allocation
# for N = 1, 2, ... until it runs out of allocations to fail; each failure
# must end in a clean error (or a full recovery) and free everything. The
# decoders' malloc family is redirected at link time (--wrap), cJSON's
# through its hooks.
pf_add_test(allocfail ${CMAKE_CURRENT_LIST_DIR}/test_allocfail.c LIBS pf_proto LABELS unit)
target_link_options(test_allocfail PRIVATE
  "LINKER:--wrap=malloc,--wrap=calloc,--wrap=realloc,--wrap=free,--wrap=strdup")

# The seed-corpus generator (not a test; deploy/fuzz.sh runs it). Built in
# every configuration so that it keeps compiling with the protocol it encodes.
add_executable(pf_make_corpus ${CMAKE_SOURCE_DIR}/fuzz/make_corpus.c)
target_link_libraries(pf_make_corpus PRIVATE pf_coordinator)
