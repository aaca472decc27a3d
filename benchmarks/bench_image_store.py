"""How to store rendered frames: encode and decode time and size of lossless formats (issue 20, item 2).

PNG work was measured at 47.5 % of a thesis sweep's CPU (encode 2.67 s and decode
1.63 s per 64 MP frame). This benchmark times, on rendered frames of the thesis sweep's
settings (night, flat shading, 8-bit RGB; the frames come from ``configs/thesis_sweep.yaml``
through the project's renderer, or from image files given on the command line):

* PNG (OpenCV/libpng) at compression levels 0, 1 (OpenCV's default), 3 and 6, with the
  SUB filter that ``render/dataset.py`` uses, and with no filter; at level 1 with zlib's
  Huffman-only and RLE strategies;
* TIFF (OpenCV/libtiff) uncompressed, with Deflate, LZW and Zstandard;
* WebP lossless (OpenCV/libwebp), 8-bit only;
* the raw array compressed with Zstandard (``zstandard``) at levels 1 and 3, one thread.

Each variant is encoded and decoded ``--repeats`` times, interleaved with the others, on
one core (``cv2.setNumThreads(1)``); the medians are printed with the size, the ratio to
today's PNG and whether the decoded frame equals the original bit for bit.

Run::

    .venv/bin/python benchmarks/bench_image_store.py [--repeats 3] [--sizes 8mp 64mp] [IMAGE.png ...]
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

cv2.setNumThreads(1)


@dataclass(frozen=True)
class Store:
    """One way to store a frame: ``encode(image) -> bytes`` and ``decode(bytes) -> image``."""

    name: str
    encode: Callable[[np.ndarray], bytes]
    decode: Callable[[bytes], np.ndarray]
    eight_bit_only: bool = False


def _cv(ext: str, params: list[int]) -> tuple[Callable[[np.ndarray], bytes], Callable[[bytes], np.ndarray]]:
    def enc(img: np.ndarray) -> bytes:
        ok, buf = cv2.imencode(ext, img, params)
        if not ok:
            raise RuntimeError(f"OpenCV cannot encode {ext}")
        return buf.tobytes()

    def dec(data: bytes) -> np.ndarray:
        out = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        if out is None:
            raise RuntimeError(f"OpenCV cannot decode {ext}")
        return out

    return enc, dec


def _zstd(level: int) -> tuple[Callable[[np.ndarray], bytes], Callable[[bytes], np.ndarray]]:
    import zstandard

    def enc(img: np.ndarray) -> bytes:
        head = np.array([img.ndim, *img.shape, img.dtype.itemsize], np.int64).tobytes()
        return head + zstandard.ZstdCompressor(level=level, threads=0).compress(np.ascontiguousarray(img).tobytes())

    def dec(data: bytes) -> np.ndarray:
        ndim = int(np.frombuffer(data[:8], np.int64)[0])
        meta = np.frombuffer(data[: 8 * (ndim + 2)], np.int64)
        shape, size = tuple(int(x) for x in meta[1:1 + ndim]), int(meta[1 + ndim])
        raw = zstandard.ZstdDecompressor().decompress(data[8 * (ndim + 2):])
        return np.frombuffer(raw, np.uint8 if size == 1 else np.uint16).reshape(shape)

    return enc, dec


def stores() -> list[Store]:
    png = cv2.IMWRITE_PNG_COMPRESSION
    flt = cv2.IMWRITE_PNG_FILTER
    tif = cv2.IMWRITE_TIFF_COMPRESSION
    out = [
        Store("png sub, level 1 (today)", *_cv(".png", [flt, cv2.IMWRITE_PNG_FILTER_SUB])),
        Store("png sub, level 0", *_cv(".png", [flt, cv2.IMWRITE_PNG_FILTER_SUB, png, 0])),
        Store("png sub, level 3", *_cv(".png", [flt, cv2.IMWRITE_PNG_FILTER_SUB, png, 3])),
        Store("png sub, level 6", *_cv(".png", [flt, cv2.IMWRITE_PNG_FILTER_SUB, png, 6])),
        Store("png no filter, level 1", *_cv(".png", [flt, cv2.IMWRITE_PNG_FILTER_NONE, png, 1])),
        Store("png sub, Huffman only", *_cv(".png", [flt, cv2.IMWRITE_PNG_FILTER_SUB, cv2.IMWRITE_PNG_STRATEGY,
                                                     cv2.IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY])),
        Store("png sub, RLE", *_cv(".png", [flt, cv2.IMWRITE_PNG_FILTER_SUB, cv2.IMWRITE_PNG_STRATEGY,
                                            cv2.IMWRITE_PNG_STRATEGY_RLE])),
        Store("tiff uncompressed", *_cv(".tiff", [tif, cv2.IMWRITE_TIFF_COMPRESSION_NONE])),
        Store("tiff deflate", *_cv(".tiff", [tif, cv2.IMWRITE_TIFF_COMPRESSION_ADOBE_DEFLATE])),
        Store("tiff lzw", *_cv(".tiff", [tif, cv2.IMWRITE_TIFF_COMPRESSION_LZW])),
        Store("tiff zstd", *_cv(".tiff", [tif, cv2.IMWRITE_TIFF_COMPRESSION_ZSTD])),
        Store("webp lossless", *_cv(".webp", [cv2.IMWRITE_WEBP_QUALITY, 101]), eight_bit_only=True),
    ]
    try:
        out += [Store("zstd raw, level 1", *_zstd(1)), Store("zstd raw, level 3", *_zstd(3))]
    except ImportError:
        print("zstandard is not installed: the raw-array variants are left out")
    probe = np.zeros((16, 16, 3), np.uint8)
    usable = []
    for s in out:  # this OpenCV build may lack a codec (its libtiff without Zstandard, say)
        try:
            s.encode(probe)
            usable.append(s)
        except RuntimeError:
            print(f"{s.name}: not available in this build, left out")
    return usable


def rendered_frame(preset: str) -> np.ndarray:
    """One frame of ``configs/thesis_sweep.yaml``'s settings for camera ``preset`` (BGR, as stored)."""
    from deckpose.render.config import config_from_dict
    from deckpose.render.frame import render_frame
    from deckpose.render.plan import plan_frames
    from deckpose.render.scene import DeckRenderer

    doc = {"name": "bench", "seed": 2024, "cameras": [{"preset": preset}], "heights_m": [40],
           "lighting": ["night"], "motion": {"source": "thesis", "max_samples": 1},
           "sensor": {"bit_depth": 8, "read_noise_e": 5}, "scene": {"shading": "flat"},
           "layout": {"n_ring": 12, "radius_m": 10.0, "has_centre": False}}
    cfg = config_from_dict(doc)
    spec = plan_frames(cfg)[0]
    camera = cfg.cameras_by_name()[spec.camera_name]
    renderer = DeckRenderer(cfg.layout, cfg.scene, cfg.deck_half_size_m(), cfg.backend)
    img = render_frame(cfg, spec, camera, renderer).frame.image
    return np.ascontiguousarray(img[..., ::-1])


def bench(name: str, img: np.ndarray, repeats: int) -> None:
    variants = [s for s in stores() if not (s.eight_bit_only and img.dtype != np.uint8)]
    enc_t: dict[str, list[float]] = {s.name: [] for s in variants}
    dec_t: dict[str, list[float]] = {s.name: [] for s in variants}
    sizes: dict[str, int] = {}
    exact: dict[str, bool] = {}
    for _ in range(repeats):  # interleaved: a pause of the shared machine hits every variant alike
        for s in variants:
            t0 = time.process_time()
            data = s.encode(img)
            enc_t[s.name].append(time.process_time() - t0)
            t0 = time.process_time()
            back = s.decode(data)
            dec_t[s.name].append(time.process_time() - t0)
            sizes[s.name] = len(data)
            exact[s.name] = back.shape == img.shape and back.dtype == img.dtype and bool(np.array_equal(back, img))
            del data, back
    ref = variants[0].name
    ref_io = np.median(enc_t[ref]) + np.median(dec_t[ref])
    h, w = img.shape[:2]
    print(f"\n{name}: {w}x{h} {img.dtype} {'RGB' if img.ndim == 3 else 'mono'}, {img.nbytes / 2**20:.0f} MiB raw; "
          f"{repeats} interleaved repeats, median CPU s; 1-minute load {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print(f"  {'store':28s} {'encode s':>9s} {'decode s':>9s} {'enc+dec':>8s} {'x today':>8s} {'MiB':>8s} {'lossless':>9s}")
    for s in variants:
        e, d = float(np.median(enc_t[s.name])), float(np.median(dec_t[s.name]))
        print(f"  {s.name:28s} {e:9.3f} {d:9.3f} {e + d:8.3f} {(e + d) / ref_io:8.2f} "
              f"{sizes[s.name] / 2**20:8.1f} {'yes' if exact[s.name] else 'NO':>9s}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("images", nargs="*", help="frames to store (default: render one per --sizes camera)")
    ap.add_argument("--sizes", nargs="+", default=["8mp", "64mp"], help="camera presets to render")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    print(f"bench_image_store: OpenCV {cv2.__version__}, one thread")
    if args.images:
        for p in args.images:
            img = cv2.imread(p, cv2.IMREAD_UNCHANGED)
            if img is None:
                raise SystemExit(f"bench_image_store: cannot read {p}")
            bench(p, img, args.repeats)
    else:
        for preset in args.sizes:
            bench(f"rendered {preset} frame (thesis sweep settings)", rendered_frame(preset), args.repeats)


if __name__ == "__main__":
    main()
