"""Setting a V4L2 camera control that OpenCV has no property for, by its ioctl.

OpenCV's V4L2 backend sets exposure, focus and the like through ``CAP_PROP_*``, but not
``exposure_auto_priority`` (``exposure_dynamic_framerate`` in newer kernels): with it on
(many UVC webcams' default), auto exposure may lengthen the exposure past the frame
period in dim light and so lower the real frame rate, while ``CAP_PROP_FPS`` still
reports the nominal one. The control is set here with ``VIDIOC_S_CTRL`` on the device
node, which V4L2 allows beside the stream OpenCV holds open. Linux only.
"""

from __future__ import annotations

import os
import struct

# _IOWR('V', 28, struct v4l2_control), the struct being {__u32 id; __s32 value;}
VIDIOC_S_CTRL = 0xC008561C
# V4L2_CID_CAMERA_CLASS_BASE (0x009A0900) + 3
V4L2_CID_EXPOSURE_AUTO_PRIORITY = 0x009A0903


def set_control(device: str, control_id: int, value: int) -> str | None:
    """Set one control of the V4L2 device node ``device``; None when it is set, else
    why not, in one line (no such node, not a V4L2 device, a control it lacks)."""
    try:
        import fcntl
    except ImportError:
        return "V4L2 controls are set on Linux only"
    try:
        fd = os.open(device, os.O_RDWR | os.O_NONBLOCK)
    except OSError as exc:
        return f"{device}: {exc.strerror}"
    try:
        fcntl.ioctl(fd, VIDIOC_S_CTRL, struct.pack("Ii", control_id, value))
    except OSError as exc:
        return f"{device} refused control {control_id:#x}: {exc.strerror}"
    finally:
        os.close(fd)
    return None
