"""Read videos back with an independent decoder: the ffmpeg binary of imageio-ffmpeg."""

import re
import subprocess

import numpy as np
import pytest

iio = pytest.importorskip("imageio_ffmpeg")
FFMPEG = iio.get_ffmpeg_exe()


def probe(path) -> dict:
    """Codec, pixel format (with colour tags), size and fps from ``ffmpeg -i``."""
    info = subprocess.run(
        [FFMPEG, "-hide_banner", "-i", str(path)], capture_output=True, text=True, check=False
    ).stderr
    line = next(x for x in info.splitlines() if "Stream #0:0" in x and "Video:" in x)
    fields = re.split(r",\s*(?![^()]*\))", line.split("Video: ", 1)[1])  # commas outside ()
    size = next(f for f in fields if re.fullmatch(r"\d+x\d+( \[.*\])?", f))
    fps = next(f for f in fields if f.endswith(" fps"))
    return {
        "codec": fields[0].split()[0],
        "pix_fmt": fields[1],
        "size": tuple(int(v) for v in size.split()[0].split("x")),
        "fps": float(fps.split()[0]),
    }


def decode(path) -> tuple[dict, list[np.ndarray]]:
    """Probe, and every frame as stored (no frame-rate conversion), ``(h, w, 3) uint8``."""
    meta = probe(path)
    raw = subprocess.run(
        [
            FFMPEG,
            "-v",
            "error",
            "-i",
            str(path),
            "-fps_mode",
            "passthrough",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgb24",
            "-",
        ],
        capture_output=True,
        check=True,
    ).stdout
    width, height = meta["size"]
    frames = np.frombuffer(raw, np.uint8).reshape(-1, height, width, 3)
    return meta, list(frames)


def frame_count(path) -> int:
    return iio.count_frames_and_secs(str(path))[0]
