# The photon kd-tree: layout rules, k-nearest and radius queries against brute
# force, determinism, and layout validation.
pf_add_test(kdtree ${CMAKE_CURRENT_LIST_DIR}/test_kdtree.c LIBS pf_common LABELS unit)

# Build and query timings; not a test (run by hand: build/bin/bench_kdtree [n...]).
add_executable(bench_kdtree ${CMAKE_CURRENT_LIST_DIR}/bench_kdtree.c)
target_link_libraries(bench_kdtree PRIVATE pf_common)
