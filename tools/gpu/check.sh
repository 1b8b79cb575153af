#!/bin/bash
# pilotlab's GPU checks on the lent machine (run from the repository root there, after tools/gpu/prepare.sh
# here; the call carries .whl): `bash tools/gpu/check.sh [cuda] [study] [suite]` (all three by default).
# cuda: tests/pilotlab/test_cuda.py and test_hardware.py; study: recipes/study2022_cuda.yaml cold, then warm,
# its report back as study2022_cuda.tgz; suite: the default test suite on 12 workers. Each part stops at
# its time limit (CUDA_S, STUDY_S, SUITE_S seconds); logs come back in $OUT.
export PYTHONUNBUFFERED=1
T0=$(date +%s)
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
    > $OUT/install.log 2>&1 || { tail -20 $OUT/install.log; exit 1; }
export PYTHONPATH=/tmp/site:$PWD/.whl/pb:$PWD
{ nvidia-smi -L; nproc; uptime
  python3 -c "import torch, onnxruntime, pybullet, pydantic, torchao, rosbags, dask; print('torch', torch.__version__, torch.cuda.is_available(), 'ort', onnxruntime.__version__, onnxruntime.get_available_providers(), 'torchao', torchao.__version__)"
  python3 -m pip list 2>/dev/null | grep -i -E "tensorrt|onnxruntime|xdist"
  echo "setup $(( $(date +%s) - T0 )) s"; } 2>&1 | tee $OUT/env.log

part() { echo "=== $1 at $(( $(date +%s) - T0 )) s"; }
ARGS="$*"
if [[ -z "$ARGS" || " $ARGS " == *" cuda "* ]]; then
  part cuda_tests
  timeout -s INT ${CUDA_S:-150} python3 -m pytest tests/pilotlab/test_cuda.py tests/pilotlab/test_hardware.py -q -rsfE \
      -p no:cacheprovider 2>&1 | tee $OUT/cuda_tests.log | tail -25
fi
if [[ -z "$ARGS" || " $ARGS " == *" study "* ]]; then
  part study
  S0=$(date +%s); uptime
  timeout -s INT ${STUDY_S:-300} python3 -m pilotlab run recipes/study2022_cuda.yaml --store /tmp/store > $OUT/study.log 2>&1
  echo "study rc=$? in $(( $(date +%s) - S0 )) s"; uptime; tail -30 $OUT/study.log
  [ -d reports/study2022_cuda ] && tar czf $OUT/study2022_cuda.tgz -C reports study2022_cuda
  S0=$(date +%s); python3 -m pilotlab run recipes/study2022_cuda.yaml --store /tmp/store > $OUT/study_warm.log 2>&1
  echo "warm rerun rc=$? in $(( $(date +%s) - S0 )) s"; tail -3 $OUT/study_warm.log
fi
if [[ -z "$ARGS" || " $ARGS " == *" suite "* ]]; then
  part suite
  timeout -s INT ${SUITE_S:-170} python3 -m pytest -q -n ${WORKERS:-12} -rfE -p no:cacheprovider > $OUT/suite.log 2>&1
  grep -E "passed|failed" $OUT/suite.log | tail -3
  grep -E "^(FAILED|ERROR) " $OUT/suite.log | head -40
fi
part end
