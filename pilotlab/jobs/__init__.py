"""pilotlab's job kinds: one thin handler per module (record, frames, train, prepare, optimize,
timing, offline, online), registered with `matrix.kinds.job_kind`."""
