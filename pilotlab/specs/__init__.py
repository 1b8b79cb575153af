"""The typed params of every job kind: one pydantic model per kind, the one home of its defaults.

Each module defines a kind's params model and registers the kind with the engine, naming its
handler by string (`pilotlab.jobs.<kind>:run_<kind>`, imported only when a job runs). The recipe's
sections and the CLI options for the same settings (`pilotlab record`, `pilotlab drive`) are built
from these models, so a default cannot disagree with itself and an unknown option is rejected in
one place. Planning imports this package, so nothing here imports torch, OpenCV or pybullet.

    base         Spec (frozen, unknown keys rejected), CameraSize, CONTROL_HZ
    record       RecordSettings (recipe + CLI), RecordSpec (the record job)
    frames       PreprocessConfig, FramesSpec
    train        AugmentConfig, TrainSettings (recipe models:), TrainSpec
    prepare      PrepareSpec (a network pruned and fine-tuned once for the strategies that convert it)
    optimize     OptimizeSpec
    timing       OfflineSettings (recipe offline:, but `data`), TimingSpec
    offline      OfflineSpec
    online       DriveSettings, LapSettings (recipe online: + `pilotlab drive`), OnlineSpec
    guesses      what a job of each kind typically takes (the scheduler's first guess; no kind's code)
"""
KIND_MODULES = tuple(f"pilotlab.specs.{kind}" for kind in ("record", "frames", "train", "prepare", "optimize",
                                                             "timing", "offline", "online", "guesses"))
