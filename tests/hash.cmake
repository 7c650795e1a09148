pf_add_test(hash test_hash.c LIBS pf_common LABELS unit)
