"""From a video to world coordinates: frames -> the people in each (detection, crops) -> tracks -> ``Lifter``."""

from ray3d.video.detectors import (
                                   DEFAULT_DETECTOR,
                                   DETECTORS,
                                   Detection,
                                   MediaPipeDetector,
                                   PeopleDetector,
                                   PoseDetector,
                                   make_detector,
)
from ray3d.video.frames import VideoInfo, camera_for_video, read_frames, read_video_info
from ray3d.video.pipeline import TrackedPeople, VideoResult, lift_video, lift_videos, track_video, video_info
from ray3d.video.track import Track
from ray3d.video.tracking import FloorTracker

__all__ = ["DEFAULT_DETECTOR", "DETECTORS", "Detection", "FloorTracker", "MediaPipeDetector", "PeopleDetector",
           "PoseDetector", "Track", "TrackedPeople", "VideoInfo", "VideoResult", "camera_for_video", "lift_video",
           "lift_videos", "make_detector", "read_frames", "read_video_info", "track_video", "video_info"]
