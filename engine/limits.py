"""Size limits on outside input, in one place.

Readers and the server refuse input beyond these with a one-line message
(``MotionFormatError`` / ``UploadError`` / ``SessionError``) instead of trying to
hold it in memory or computing with it. The numbers are far above any real
capture (the longest shared take is 4,587 frames; a 2-minute 120 fps take is
14,400; the largest skeleton, BEAT's, has 56 joints) and far below what would
exhaust memory on a small server.
"""

from __future__ import annotations

#: joints in one skeleton (BVH).
MAX_JOINTS = 1_000
#: frames (data rows) in one take, any format: 4.6 hours at 120 fps.
MAX_FRAMES = 2_000_000
#: markers in one marker set (C3D, TRC).
MAX_MARKERS = 10_000
#: frame rate, frames per second (a BVH ``Frame Time`` below 0.1 ms is refused).
MAX_FPS = 10_000.0
#: magnitude of any offset, position or angle value in a capture file (file units or
#: degrees); larger values overflow forward kinematics and are never real.
MAX_ABS_VALUE = 1e9
#: bytes of one uploaded capture file (the web app; sent in chunks): a 10-minute
#: 120 fps BVH with fingers is about 250 MB, a 2-minute one about 50 MB.
MAX_UPLOAD_BYTES = 200 * 1024 * 1024
#: bytes of one session JSON file.
MAX_SESSION_BYTES = 4 * 1024 * 1024
#: rows of a batch manifest.
MAX_MANIFEST_ROWS = 100_000
