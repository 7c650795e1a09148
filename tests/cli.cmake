# End-to-end tests of the photonfarm command line (tests/test_cli.sh): exit
# codes, messages, PNG and PFM output, determinism, compare and --terms, with
# tiny renders of the shipped scenes and the broken scenes in tests/data/cli/.
add_test(NAME cli
         COMMAND bash ${CMAKE_SOURCE_DIR}/tests/test_cli.sh $<TARGET_FILE:photonfarm>
         WORKING_DIRECTORY ${CMAKE_SOURCE_DIR})
set_tests_properties(cli PROPERTIES LABELS "integration" TIMEOUT 300)
