"""What the edge-runtime strategies (LiteRT) share: they run only where their optional packages are
installed (`pip install -e '.[edge]'`). Their configs register them with `requires=LITERT_CONVERTER,
extra=EXTRA`, so where one is missing they are "not applicable" with the install line, and their
handler modules (which import TensorFlow at their top) are never imported. Their artifacts run on
the CPU only (XNNPACK), which the predictor checks."""
from __future__ import annotations

EXTRA = "edge"
LITERT_CONVERTER = ("tensorflow", "tf_keras", "onnx2tf", "onnx_graphsurgeon", "ai_edge_litert")
