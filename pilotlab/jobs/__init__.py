"""Job kinds: one thin handler per kind, registered with matrix.kinds.job_kind on import."""
