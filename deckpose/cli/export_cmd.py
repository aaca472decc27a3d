"""``deckpose export``: a run as a BOP or COCO-keypoints dataset."""

from __future__ import annotations

import argparse
from pathlib import Path

from deckpose.cli.common_options import HelpFormatter, add_output, add_progress, frame_bar
from deckpose.cli.console import wrote

#: The formats ``--format`` takes.
FORMATS = ("bop", "coco")


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "export",
        help="write a run's images and ground truth as a BOP or COCO-keypoints dataset",
        description=(
            "Write RUN (a rendered dataset) into DIR in a standard format. "
            "bop: the BOP toolkit's scene-wise format: DIR/models/obj_000001.ply (the deck, mm, "
            "vertex i = beacon id i) with models_info.json, one scene per camera under DIR/test/ "
            "(scene_camera.json: cam_K, depth_scale; scene_gt.json: cam_R_m2c, cam_t_m2c in mm = "
            "T_cam_from_deck; rgb/ images named by frame id), test_targets_bop19.json and "
            "dataset_info.md. BOP's camera has no lens distortion, so a run with a distorted camera "
            "is refused; no depth, masks or scene_gt_info.json are written. "
            "coco: DIR/deck_keypoints.json with one category 'deck' whose keypoints are the "
            "beacons (bow, ring_1.., centre; skeleton: ring edges and spokes), per image one "
            "annotation with [x, y, v] per beacon (v=2 visible, 1 in the image but seen from below, "
            "0 outside with x=y=0), bbox and area of the labelled keypoints; images in DIR/images/. "
            "Pixels: cam_K keeps OpenCV's convention (pixel centres at integers); COCO's keypoints "
            "are x = u + 0.5, y = v + 0.5 (0, 0 the top-left corner of the image), distortion "
            "included. Images are absolute symbolic links into RUN unless --copy-images."
        ),
        formatter_class=HelpFormatter,
    )
    p.add_argument("run", type=Path, help="run folder (made by deckpose render)")
    p.add_argument("--format", required=True, choices=FORMATS, dest="format",
                   help="bop (BOP scene-wise dataset) or coco (COCO keypoints)")
    add_output(p, "dataset folder to write: new or empty, or an earlier export of the same format "
                  "(whose files are replaced)",
               required=True, metavar="DIR")
    p.add_argument("--copy-images", action="store_true",
                   help="copy the images instead of linking them (a self-contained folder to move "
                        "or archive; slow for large frames)")
    add_progress(p)
    p.set_defaults(func=run_export)


def run_export(args: argparse.Namespace) -> int:
    from deckpose.evaluate.export_images import ImageMode
    from deckpose.output_folder import claim_output
    from deckpose.run_folder import require_dataset, run_paths

    run = run_paths(args.run)
    require_dataset(run)  # not a run folder: one line before the output folder is made
    _refuse_foreign_folder(args.output, args.format)
    out = claim_output(args.output, what="export")
    images = ImageMode.COPY if args.copy_images else ImageMode.SYMLINK
    with frame_bar(f"export ({args.format})", enabled=not args.no_progress) as bar:
        if args.format == "bop":
            from deckpose.evaluate.export_bop import write_bop

            bop = write_bop(run, out, images=images, progress=bar.update)
            scenes = ", ".join(f"{s:06d} = {c}" for s, c in bop.scenes.items())
            wrote(args, bop.root, f"BOP dataset of {bop.n_images} images written to {bop.root} (scenes {scenes}; "
                  f"model {bop.model})")
        else:
            from deckpose.evaluate.export_coco import write_coco

            coco = write_coco(run, out, images=images, progress=bar.update)
            wrote(args, coco.annotations, f"COCO keypoints of {coco.n_images} images ({coco.n_annotations} "
                  f"annotations) written to {coco.annotations}")
    return 0


def _refuse_foreign_folder(out: Path, fmt: str) -> None:
    """Refuse a folder that holds files but no earlier export of ``fmt`` of ours (whose files may be replaced)."""
    from deckpose.errors import ConfigError
    from deckpose.evaluate.export_bop import is_bop_export
    from deckpose.evaluate.export_coco import is_coco_export

    if not out.is_dir():
        return
    held = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    earlier = is_coco_export(out) if fmt == "coco" else is_bop_export(out)
    if held and not earlier:
        raise ConfigError(f"-o {out} holds files no deckpose {fmt} export wrote ({', '.join(held[:3])}"
                          f"{', ...' if len(held) > 3 else ''}), which the export could replace; give a new "
                          "or empty folder (or remove this one, if an interrupted export left it)")
