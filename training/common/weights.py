"""The mcdenoise weights file (".mcdnw"): one format for every network of the project.

Written here from a PyTorch state_dict, read in C++ by mcdn::nn::read_weights
(lib/src/nn/nn.h, which has the same layout description). Little-endian:

    magic      8 bytes  b"MCDNNWTS"
    version    uint32   1
    metadata   uint32 byte count + UTF-8 JSON (network name, hyper-parameters, training)
    count      uint32   number of tensors, then per tensor:
      name     uint32 byte count + UTF-8 (the state_dict key, e.g. "enc1.weight")
      rank     uint32, then rank x uint32 dims, outermost first
      data     float32 values, row-major (C order)

Convolution weights keep PyTorch's OIHW order [out, in, kh, kw]; biases are [out].

    from weights import write_weights, read_weights
    write_weights("mix.mcdnw", model.state_dict(), {"network": "mix", "channels": 48})
    metadata, tensors = read_weights("mix.mcdnw")   # dict, {name: float32 ndarray}
"""
import json
import struct

import numpy as np

MAGIC = b"MCDNNWTS"
VERSION = 1


def _as_array(value):
    """float32 C-order ndarray from a torch tensor or anything numpy accepts."""
    if hasattr(value, "detach"):
        value = value.detach().cpu().numpy()
    return np.ascontiguousarray(np.asarray(value, dtype=np.float32))


def write_weights(path, tensors, metadata=None):
    """Writes `tensors` (a state_dict or {name: array}) and `metadata` (a dict, stored as
    JSON, or a string stored as is). Buffers that are not parameters (e.g. BatchNorm's
    num_batches_tracked) should be removed by the caller: every tensor is loaded by name."""
    if metadata is None:
        metadata = {}
    text = metadata if isinstance(metadata, str) else json.dumps(metadata, sort_keys=True)
    meta_bytes = text.encode("utf-8")
    out = bytearray(MAGIC)
    out += struct.pack("<II", VERSION, len(meta_bytes)) + meta_bytes
    out += struct.pack("<I", len(tensors))
    for name, value in tensors.items():
        array = _as_array(value)
        if array.ndim == 0:
            array = array.reshape(1)
        name_bytes = name.encode("utf-8")
        out += struct.pack("<I", len(name_bytes)) + name_bytes
        out += struct.pack("<I", array.ndim) + struct.pack("<%dI" % array.ndim, *array.shape)
        out += array.astype("<f4").tobytes()
    with open(path, "wb") as f:
        f.write(out)


def read_weights(path):
    """Returns (metadata, {name: float32 ndarray}); metadata is a dict when it is JSON."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != MAGIC:
        raise ValueError("%s: not a mcdenoise weights file" % path)
    version, meta_len = struct.unpack_from("<II", data, 8)
    if version != VERSION:
        raise ValueError("%s: weights format version %d, this reader reads %d" % (path, version, VERSION))
    pos = 16
    text = data[pos:pos + meta_len].decode("utf-8")
    pos += meta_len
    try:
        metadata = json.loads(text) if text else {}
    except ValueError:
        metadata = text
    (count,) = struct.unpack_from("<I", data, pos)
    pos += 4
    tensors = {}
    for _ in range(count):
        (name_len,) = struct.unpack_from("<I", data, pos)
        name = data[pos + 4:pos + 4 + name_len].decode("utf-8")
        pos += 4 + name_len
        (rank,) = struct.unpack_from("<I", data, pos)
        shape = struct.unpack_from("<%dI" % rank, data, pos + 4)
        pos += 4 + 4 * rank
        size = int(np.prod(shape)) if rank else 1
        if pos + 4 * size > len(data):
            raise ValueError("%s: truncated in the data of tensor '%s'" % (path, name))
        tensors[name] = np.frombuffer(data, dtype="<f4", count=size, offset=pos).reshape(shape).copy()
        pos += 4 * size
    if pos != len(data):
        raise ValueError("%s: %d unexpected bytes after the last tensor" % (path, len(data) - pos))
    return metadata, tensors
