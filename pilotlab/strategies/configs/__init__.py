"""The strategies' configs: each module holds the frozen, versioned config dataclasses of one
strategy family and registers each strategy with its handler named by string. Importing this
package registers every strategy and imports no handler (so no torch, onnx, onnxruntime, torchao
or tensorflow): planning needs only the names and the configs.

Every module of this folder is imported, found on disk: a new strategy's config module is registered
without an edit here, so adding one changes no other strategy's code (this file is in every optimize
job's code, as the package each config module is imported through)."""
import importlib
import pkgutil

for _found in sorted(pkgutil.iter_modules(__path__), key=lambda module: module.name):
    importlib.import_module(f"{__name__}.{_found.name}")
