"""matrix: a small, generic engine — recipe -> grid -> job DAG -> cached, incremental execution.

It knows nothing of driving: a domain registers its job kinds (`matrix.kinds.job_kind`), its recipe
sections and a planner that turns a validated recipe into jobs.
"""
from matrix.errors import CycleError, MatrixError, RecipeError, UnknownNameError  # noqa: F401
from matrix.kinds import DepResult, JobContext, NotApplicable, job_kind  # noqa: F401
from matrix.registry import Registry  # noqa: F401
