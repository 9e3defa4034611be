"""From a video to world coordinates: a 2D pose detector behind a small interface, then ``Lifter``."""

from ray3d.video.detectors import DETECTORS, MediaPipeDetector, PoseDetector, make_detector
from ray3d.video.pipeline import VideoResult, detect_video, lift_video, read_video_info, video_keypoints

__all__ = ["DETECTORS", "MediaPipeDetector", "PoseDetector", "VideoResult", "detect_video", "lift_video",
           "make_detector", "read_video_info", "video_keypoints"]
