"""The benchmark scripts of ``bench/`` as modules, for tests that check a benchmark's own
truth models (``bench/truth_model.py``, ``truth_matrix.py``, ``truth_targets.py``,
``truth_stand.py``) against the package.

``bench/`` is not a package; :func:`load_bench` imports one script by path under the name
``fae_bench_<name>`` (registered in ``sys.modules``, so a dataclass in it pickles; each call
runs the script afresh). Tests import it as ``from bench_modules import load_bench``
(``test/`` is on ``sys.path`` through ``test/conftest.py``).
"""
from __future__ import annotations

import importlib.util
from pathlib import Path
import sys
from types import ModuleType

BENCH = Path(__file__).resolve().parents[1] / 'bench'


def load_bench(name: str) -> ModuleType:
    """``bench/<name>.py`` as the module ``fae_bench_<name>``."""
    key = f'fae_bench_{name}'
    spec = importlib.util.spec_from_file_location(key, BENCH / f'{name}.py')
    if spec is None or spec.loader is None:
        raise ImportError(f'no benchmark script {BENCH / name}.py')
    module = importlib.util.module_from_spec(spec)
    sys.modules[key] = module
    spec.loader.exec_module(module)
    return module
