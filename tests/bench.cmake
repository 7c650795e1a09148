# The benchmark harness's smoke test (bench/test_bench.py, ctest bench_smoke,
# label bench): the log parser, reference choice, the child's own peak RSS
# from wait4, timeouts, the docs markers, the time-limit/quality families'
# detection, failing and hanging renderers (a stand-in script), and two tiny
# cornell-box renders end to end (CSV with finite errors, markdown, PNG plot;
# the plot needs gnuplot: deploy/install-deps.sh --test installs it). About
# ten seconds. The full sweep is not a test: python3 bench/bench.py.
find_program(PF_PYTHON3 python3)
if(TARGET photonfarm AND PF_PYTHON3)
  add_test(NAME bench_smoke
           COMMAND ${PF_PYTHON3} ${CMAKE_SOURCE_DIR}/bench/test_bench.py --photonfarm $<TARGET_FILE:photonfarm>
           WORKING_DIRECTORY ${CMAKE_SOURCE_DIR})
  set_tests_properties(bench_smoke PROPERTIES LABELS "bench" TIMEOUT 120)
else()
  message(STATUS "bench_smoke test skipped: no python3 or no photonfarm target")
endif()
