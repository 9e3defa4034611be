"""Jobs: what a user asks for (inputs, their cameras, the detector, the model, the options, the outputs), resolved
once (``job``) and run (``run``: an input lifted, several cameras fused and written; ``live``: streams followed).
The command line, batch manifests, live and the benchmarks all go through here."""

from ray3d.jobs.job import CameraChoice, Job, input_kind
from ray3d.jobs.run import (InputResult, fuse_and_write, lift_cameras_together, run_input, run_videos_together,
                            video_input)

__all__ = ["CameraChoice", "InputResult", "Job", "fuse_and_write", "input_kind", "lift_cameras_together",
           "run_input", "run_videos_together", "video_input"]
