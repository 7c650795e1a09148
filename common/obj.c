/* obj.c: not written yet. */
typedef int pf_placeholder_obj;
