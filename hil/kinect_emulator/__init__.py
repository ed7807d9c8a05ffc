"""Kinect v1 emulator for the hardware-in-loop rig.

Renders 640x480 RGB + 16-bit depth (mm) from a camera pose inside a box room whose walls, floor,
ceiling and obstacles are textured with real photographs (TUM RGB-D frames shipped in tests/data),
with Kinect-like depth noise, disparity quantisation, range limits, projector shadows and dropouts,
and writes the frames where the real rgbd-streamer's capture sources read them (TUM folder, fakenect
dump) - offline, or live from the craft's current pose (LiveKinect: a fakenect dump whose INDEX.txt
is a FIFO, fed by a renderer child process).
"""

from kinect_emulator.live import LiveFrameRecord, LiveKinect, match_capture_stamps
from kinect_emulator.poses import camera_pose_from_ned, pose_matrix
from kinect_emulator.renderer import Intrinsics, KinectEmulator, KinectFrame, KinectOptions
from kinect_emulator.room import Box, Room, default_room, load_textures
from kinect_emulator.writers import FakenectDumpWriter, TumFolderWriter

__all__ = [
    "Box",
    "Room",
    "default_room",
    "load_textures",
    "KinectFrame",
    "KinectEmulator",
    "KinectOptions",
    "Intrinsics",
    "FakenectDumpWriter",
    "TumFolderWriter",
    "LiveKinect",
    "LiveFrameRecord",
    "match_capture_stamps",
    "camera_pose_from_ned",
    "pose_matrix",
]
