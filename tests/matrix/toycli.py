"""`python -m tests.matrix.toycli run recipe.yaml --store S`: the engine's CLI on the toy domain."""
import sys

from matrix.cli import main
from tests.matrix.toydomain import TOY

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:], TOY, prog="toy"))
