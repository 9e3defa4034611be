"""The lifting wing: users' keypoints of one camera -> world joints. ``runner`` (``ModelRunner``: a model loaded
and run on windows, whatever its backend), ``lifter`` (``Lifter``: a track or many, one camera or several, on the
runner), ``floor_pass`` (a camera's tracks through the network, the floor they share decided, each refined on it),
``tracks`` (a camera's tracks prepared and gathered), ``stream`` (``LiftStream``: one frame at a time, the same
network on the same windows), ``inputs`` (what a model reads of users' keypoints: checks, stand-ins for joints never
seen, confidences in the model's layout) and ``options`` (one lift's or one video's options, as the CLI, batch
manifests and live pass them)."""
