"""Reading and writing mono WAV files, with errors that name the file.

Reads RIFF/WAVE with integer PCM (8/16/24/32-bit) or IEEE float (32/64-bit) samples, plain or
WAVE_FORMAT_EXTENSIBLE (the real DualTalk release stores 32-bit float, 16 kHz mono). Writes 16-bit PCM.
Integer samples map to float32 as k / 2^(bits-1) (16-bit: k / 32768), the usual convention.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dyadbench.arrays import require_file
from dyadbench.atomic import write_bytes
from dyadbench.errors import InputError

PCM, IEEE_FLOAT, EXTENSIBLE = 1, 3, 0xFFFE
PCM16_SCALE = 32768.0


@dataclass(frozen=True)
class WavInfo:
    path: Path
    sample_rate: int
    channels: int
    bits: int
    encoding: str  # "pcm" or "float"
    num_samples: int  # per channel
    data_offset: int

    @property
    def duration_s(self) -> float:
        return self.num_samples / self.sample_rate


def pcm16_to_float(samples: np.ndarray) -> np.ndarray:
    """int16 -> float32 k / 32768."""
    return samples.astype(np.float32) / np.float32(PCM16_SCALE)


def float_to_pcm16(audio: np.ndarray) -> np.ndarray:
    """float -> int16 round(x * 32768), clipped to [-32768, 32767] (exact in float32: x * 2^15 is exact)."""
    scaled = np.multiply(np.asarray(audio, dtype=np.float32), np.float32(PCM16_SCALE))
    np.rint(scaled, out=scaled)
    np.clip(scaled, -32768, 32767, out=scaled)
    return scaled.astype(np.int16)


def wav_info(path: str | Path) -> WavInfo:
    """Parse the header of a WAV file (no samples read); raises InputError on anything malformed."""
    path = require_file(path)
    try:
        with open(path, "rb") as f:
            head = f.read(12)
            size = path.stat().st_size
            if len(head) < 12 or head[:4] != b"RIFF" or head[8:12] != b"WAVE":
                raise InputError(path, "not a RIFF/WAVE file")
            fmt = None
            pos = 12
            while pos + 8 <= size:
                f.seek(pos)
                chunk_id, chunk_size = struct.unpack("<4sI", f.read(8))
                if chunk_id == b"fmt ":
                    raw = f.read(chunk_size)
                    if len(raw) < 16:
                        raise InputError(path, "truncated fmt chunk")
                    fmt = struct.unpack("<HHIIHH", raw[:16])
                    if fmt[0] == EXTENSIBLE and len(raw) >= 26:
                        fmt = (struct.unpack("<H", raw[24:26])[0],) + fmt[1:]
                elif chunk_id == b"data":
                    if fmt is None:
                        raise InputError(path, "data chunk before fmt chunk")
                    return _info(path, fmt, chunk_size, pos + 8, size)
                pos += 8 + chunk_size + (chunk_size & 1)
    except OSError as exc:
        raise InputError(path, f"cannot read: {exc.strerror or exc}") from None
    raise InputError(path, "no data chunk (truncated or not a WAV file)")


def _info(path: Path, fmt: tuple, data_size: int, offset: int, file_size: int) -> WavInfo:
    tag, channels, rate, _, block_align, bits = fmt
    if tag == PCM and bits in (8, 16, 24, 32):
        encoding = "pcm"
    elif tag == IEEE_FLOAT and bits in (32, 64):
        encoding = "float"
    else:
        raise InputError(path, f"unsupported WAV encoding (format tag {tag}, {bits} bits); "
                               "use integer PCM or 32/64-bit float")
    if channels < 1 or block_align != channels * bits // 8:
        raise InputError(path, f"inconsistent WAV header ({channels} channels, block align {block_align})")
    available = file_size - offset
    if data_size > available:
        raise InputError(path, f"truncated: header announces {data_size} bytes of samples, "
                               f"the file holds {available}")
    return WavInfo(path, rate, channels, bits, encoding, data_size // block_align, offset)


def require_format(info: WavInfo, sample_rate: int | None = 16_000) -> WavInfo:
    """Raise InputError unless the file is mono and (unless ``sample_rate`` is None) at that rate."""
    if info.channels != 1:
        raise InputError(info.path, f"expected mono audio, got {info.channels} channels")
    if sample_rate is not None and info.sample_rate != sample_rate:
        raise InputError(info.path, f"expected {sample_rate} Hz audio, got {info.sample_rate} Hz")
    return info


def read_wav(path: str | Path, *, sample_rate: int | None = 16_000) -> np.ndarray:
    """Mono float32 samples of ``path``. Requires mono and, unless ``sample_rate`` is None, that rate."""
    info = require_format(wav_info(path), sample_rate)
    width = info.bits // 8
    with open(info.path, "rb") as f:
        f.seek(info.data_offset)
        raw = f.read(info.num_samples * width)
    if info.encoding == "float":
        audio = np.frombuffer(raw, dtype=f"<f{width}").astype(np.float32)
    elif info.bits == 24:
        b = np.frombuffer(raw, dtype=np.uint8).reshape(-1, 3).astype(np.int32)
        ints = (b[:, 0] | (b[:, 1] << 8) | (b[:, 2] << 16))
        ints = np.where(ints >= 1 << 23, ints - (1 << 24), ints)
        audio = (ints / float(1 << 23)).astype(np.float32)
    elif info.bits == 8:
        audio = ((np.frombuffer(raw, dtype=np.uint8).astype(np.float32) - 128.0) / 128.0).astype(np.float32)
    elif info.bits == 16:
        audio = pcm16_to_float(np.frombuffer(raw, dtype="<i2"))
    else:
        audio = (np.frombuffer(raw, dtype="<i4") / float(1 << 31)).astype(np.float32)
    if not np.all(np.isfinite(audio)):
        raise InputError(info.path, "audio contains non-finite samples (NaN or inf)")
    return audio


def wav_bytes(audio: np.ndarray, sample_rate: int = 16_000) -> bytes:
    """A complete 16-bit PCM mono WAV file as bytes."""
    audio = np.asarray(audio)
    if audio.ndim != 1:
        raise InputError(None, f"WAV writing needs mono audio (S,), got shape {audio.shape}")
    if not np.all(np.isfinite(audio)):
        raise InputError(None, "audio to write contains non-finite samples")
    data = float_to_pcm16(audio).astype("<i2").tobytes()
    header = struct.pack("<4sI4s4sIHHIIHH4sI", b"RIFF", 36 + len(data), b"WAVE", b"fmt ", 16, PCM, 1,
                         sample_rate, sample_rate * 2, 2, 16, b"data", len(data))
    return header + data


def write_wav(path: str | Path, audio: np.ndarray, sample_rate: int = 16_000) -> Path:
    """Atomically write mono 16-bit PCM."""
    try:
        data = wav_bytes(audio, sample_rate)
    except InputError as exc:
        raise InputError(path, exc.problem) from None
    return write_bytes(path, data)
