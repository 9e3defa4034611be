"""Benchmarks users can run (``ray3d bench``): accuracy (real recordings, level cameras, robustness sweeps,
calibration), speed, who is who (``identity``) and who is found (``people``) on an annotated video, live runs measured
from outside (``live``), several cameras fused against known truth (``fusion``), two runs' worlds compared
(``worlds``). Each gets its lifter, detector and cameras as a job does (``ray3d.jobs``)."""
