"""The strategies' configs: each module holds the frozen, versioned config dataclasses of one
strategy family and registers each strategy with its handler named by string. Importing this
package registers every strategy and imports no handler (so no torch, onnx, onnxruntime, torchao
or tensorflow): planning needs only the names and the configs."""
from pilotlab.strategies.configs import (  # noqa: F401  (each module registers its strategies)
    baseline, cluster, cuda, half, litert, mot, onnx_runtime, prune, prune_quant, pt2e,
    structured_prune, structured_prune_int8, structured_prune_xnnpack, torchscript,
)
