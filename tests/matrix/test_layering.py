"""matrix/ is the generic engine: it must never import the driving domain or its heavy libraries."""
import ast
from pathlib import Path

FORBIDDEN = {"pilotlab", "torch", "pybullet", "cv2", "rosbags", "onnx", "onnxruntime", "torchao"}
MATRIX = Path(__file__).resolve().parents[2] / "matrix"


def imported_roots(path: Path) -> set[str]:
    roots = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            roots |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            roots.add(node.module.split(".")[0])
    return roots


def test_matrix_never_imports_the_domain():
    files = sorted(MATRIX.rglob("*.py"))
    assert files, "matrix/ has no python files"
    offenders = {str(f.relative_to(MATRIX)): sorted(imported_roots(f) & FORBIDDEN) for f in files}
    assert {f: r for f, r in offenders.items() if r} == {}
