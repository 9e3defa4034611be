"""Jobs: what a user asks for (inputs, their cameras, the detector, the model, the options, the outputs), resolved
once (``job``) and run (``run``: ``run_job`` the whole job, its inputs lifted, several cameras fused, the outputs
and the site's report written; ``live``: streams followed, with the same tail).
The command line, batch manifests, live and the benchmarks all go through here."""

from ray3d.jobs.job import CameraChoice, Job, input_kind, load_lifter
from ray3d.jobs.run import (
                            InputResult,
                            JobResult,
                            SiteReport,
                            check_site_outputs,
                            fuse_and_write,
                            lift_cameras_together,
                            run_input,
                            run_job,
                            run_videos_together,
                            site_folder,
                            site_report,
                            video_input,
)

__all__ = ["CameraChoice", "InputResult", "Job", "JobResult", "SiteReport", "check_site_outputs", "fuse_and_write",
           "input_kind", "lift_cameras_together", "load_lifter", "run_input", "run_job", "run_videos_together",
           "site_folder", "site_report", "video_input"]
