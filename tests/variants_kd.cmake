# KD variants (as_add_variant is defined in variants.cmake), and the KD unit
# tests: determinism, cancellation, degenerate inputs, validation, ropes
# conversion.
as_add_variant(kd_midcut kd midcut kd-standard)
as_add_variant(kd_sah kd sah kd-standard)
as_add_variant(kd_ropes_midcut kd midcut kd-ropes)
as_add_variant(kd_ropes_sah kd sah kd-ropes)
