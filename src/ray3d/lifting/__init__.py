"""The lifting wing: users' keypoints of one camera -> world joints. ``lifter`` (``Lifter``: load a model, lift a
track or many, the refinement after), ``stream`` (``LiftStream``: one frame at a time, the same network on the
same windows), ``inputs`` (what a model reads of users' keypoints: checks, stand-ins for joints never seen,
confidences in the model's layout) and ``options`` (one lift's or one video's options, as the CLI, batch
manifests and live pass them)."""
