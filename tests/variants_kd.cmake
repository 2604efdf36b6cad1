# KD variants (as_add_variant is defined in variants.cmake), and the KD unit
# tests: determinism, cancellation, degenerate inputs, validation, ropes
# conversion.
as_add_variant(kd_midcut kd midcut kd-standard)
as_add_variant(kd_sah kd sah kd-standard)
as_add_variant(kd_ropes_midcut kd midcut kd-ropes)
as_add_variant(kd_ropes_sah kd sah kd-ropes)
as_add_test(test_kd_midcut SOURCES test_kd.c ARGS midcut LABELS kd)
add_test(NAME test_kd_sah COMMAND test_kd_midcut sah)
set_tests_properties(test_kd_sah PROPERTIES SKIP_RETURN_CODE 77 LABELS kd)
as_add_stiff(kd_midcut kd midcut kd-standard)
as_add_stiff(kd_sah kd sah kd-standard)
as_add_stiff(kd_ropes_midcut kd midcut kd-ropes)
as_add_stiff(kd_ropes_sah kd sah kd-ropes)
