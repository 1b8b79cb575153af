"""pilotlab's job kinds, one thin handler per module, registered with `matrix.kinds.job_kind`."""
