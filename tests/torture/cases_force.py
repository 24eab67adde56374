"""Class 1, data loss: --force may replace a previous rodfab job (recognisable by its manifest) and
nothing else; no command may write over its own input. The user's files must be byte-identical
afterwards (the engine compares checksums of everything that was there before)."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from engine import Case, Step
from fixtures import BAR, USER_FILES, bar, cantilever, design, folder, job, symlink_to

REFUSED = {1, 2}  # a clear refusal: bad input (1) or a bad command line (2), never 0
# how a message may name the current folder
CWD_NAMES = ["{cwd}", "'.'", "\".\"", "./", "current folder", "current directory", "working directory"]


def copy_of(relpath: str):
    def build(path: Path, ctx) -> None:
        shutil.copyfile(ctx.src / relpath, path)
    return build


def hardlink_to(target: str):
    def build(path: Path, ctx) -> None:
        os.link(path.parent / target, path)
    return build


def user_zip(path: Path, ctx) -> None:
    import zipfile
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("holiday/IMG_0001.jpg", b"\xff\xd8\xff" + bytes(1000))
        z.writestr("notes.txt", "not a print job\n")


def refuse(name: str, argv: list[str], files: dict, where: list[str], note: str) -> Case:
    return Case(name, [Step(argv, expect=REFUSED, where=where)], files=files, note=note)


def keep_input(name: str, argv: list[str], files: dict, output: str, where: list[str], note: str) -> Case:
    """The output is another name for an input (a link): refusing is right, and so is replacing the
    link itself by a new file; writing through it into the input is data loss."""
    return Case(name, [Step(argv, expect={0, 1, 2}, where=where, outputs=[output], replaces=[output])], files=files,
                note=note)


def cases(ctx) -> list[Case]:
    d = {"d.json": BAR}
    user = folder(USER_FILES)
    cs = [
        refuse("slice-force-user-folder-dir", ["slice", "d.json", "-o", "mydata", "--format", "dir", "--force"],
               {**d, "mydata": user}, ["mydata"], "a user's folder is not a job"),
        refuse("slice-force-user-folder-zip", ["slice", "d.json", "-o", "mydata", "--force"],
               {**d, "mydata": user}, ["mydata"], "zip output onto a user's folder"),
        refuse("slice-force-user-folder-slash", ["slice", "d.json", "-o", "project/", "--format", "dir", "--force"],
               {**d, "project": user}, ["project"], "trailing slash"),
        refuse("slice-force-user-folder-dotdot", ["slice", "d.json", "-o", "sub/../project", "--format", "dir", "--force"],
               {**d, "project": user, "sub/.keep": ""}, ["project"], "the folder reached through sub/.."),
        refuse("slice-force-cwd", ["slice", "d.json", "-o", ".", "--format", "dir", "--force"],
               {**d, "notes.txt": "mine\n"}, CWD_NAMES, "the current folder holds the design itself"),
        refuse("slice-force-empty-folder", ["slice", "d.json", "-o", "empty", "--format", "dir", "--force"],
               {**d, "empty/.keep": ""}, ["empty"], "a folder without a rodfab manifest"),
        refuse("slice-force-foreign-manifest", ["slice", "d.json", "-o", "webapp", "--format", "dir", "--force"],
               {**d, "webapp/manifest.json": json.dumps({"name": "my-web-app", "version": "1.0.0"}),
                "webapp/index.html": "<html></html>\n"}, ["webapp"], "a manifest.json that is not a rodfab job's"),
        refuse("slice-force-design-manifest", ["slice", "d.json", "-o", "fake", "--format", "dir", "--force"],
               {**d, "fake/manifest.json": BAR, "fake/keep.txt": "x\n"}, ["fake"], "manifest.json of another format"),
        refuse("slice-force-user-zip", ["slice", "d.json", "-o", "photos.zip", "--force"],
               {**d, "photos.zip": user_zip}, ["photos.zip"], "a zip that is not a rodfab job"),
        refuse("slice-force-text-file", ["slice", "d.json", "-o", "notes.txt", "--force"],
               {**d, "notes.txt": "shopping list\n"}, ["notes.txt"], "a plain file"),
        refuse("slice-force-folder-named-zip", ["slice", "d.json", "-o", "archive.zip", "--force"],
               {**d, "archive.zip": user}, ["archive.zip"], "a user's folder named like a zip"),
        refuse("slice-force-own-design", ["slice", "d.json", "-o", "d.json", "--force"],
               d, ["d.json"], "the job would replace its own design"),
        refuse("slice-force-own-design-dotslash", ["slice", "d.json", "-o", "./d.json", "--format", "dir", "--force"],
               d, ["d.json"], "the design, spelled differently"),
        refuse("slice-force-own-calibration", ["slice", "d.json", "--calibration", "cal.json", "-o", "cal.json", "--force"],
               {**d, "cal.json": copy_of("examples/calibration/default-60C.json")}, ["cal.json"], "its calibration"),
        refuse("slice-force-own-profile", ["slice", "d.json", "--profile", "./p.json", "-o", "p.json", "--force"],
               {**d, "p.json": copy_of("printer_profiles/stratasys-objet500-connex3.json")}, ["p.json"], "its profile"),
        refuse("slice-force-symlink-to-user-folder", ["slice", "d.json", "-o", "link", "--format", "dir", "--force"],
               {**d, "mydata": user, "link": symlink_to("mydata")}, ["link", "mydata"], "a link to a user's folder"),
        refuse("slice-force-symlink-to-design", ["slice", "d.json", "-o", "out.zip", "--force"],
               {**d, "out.zip": symlink_to("d.json")}, ["out.zip", "d.json"], "a link to its own design"),
        refuse("slice-no-force-user-folder", ["slice", "d.json", "-o", "mydata", "--format", "dir"],
               {**d, "mydata": user}, ["mydata"], "without --force"),
        refuse("coupons-force-user-folder", ["coupons", "-o", "mydata", "--format", "dir", "--force", "--fractions", "0,1",
                                             "--size", "3x2x0.3"],
               {"mydata": user}, ["mydata"], "coupons onto a user's folder"),
        refuse("coupons-force-user-zip", ["coupons", "-o", "photos.zip", "--force", "--fractions", "0,1", "--size", "3x2x0.3"],
               {"photos.zip": user_zip}, ["photos.zip"], "coupons onto a user's zip"),
        refuse("coupons-force-cwd", ["coupons", "-o", ".", "--format", "dir", "--force", "--fractions", "0,1",
                                     "--size", "3x2x0.3"],
               {"notes.txt": "mine\n"}, CWD_NAMES, "coupons onto the current folder"),
        # Commands that must not write over their own input.
        refuse("calibrate-output-is-input", ["calibrate", "data.csv", "-o", "data.csv"],
               {"data.csv": copy_of("examples/calibration/vero-tango-60C.csv")}, ["data.csv"], "-o DATA"),
        refuse("calibrate-plot-is-input", ["calibrate", "--plot", "data.csv", "data.csv"],
               {"data.csv": copy_of("examples/calibration/vero-tango-60C.csv")}, ["data.csv"], "--plot DATA"),
        refuse("calibrate-output-is-input-dotslash", ["calibrate", "data.csv", "-o", "./sub/../data.csv"],
               {"data.csv": copy_of("examples/calibration/vero-tango-60C.csv"), "sub/.keep": ""}, ["data.csv"],
               "-o DATA spelled differently"),
        keep_input("calibrate-output-symlink-to-input", ["calibrate", "data.csv", "-o", "cal.json"],
               {"data.csv": copy_of("examples/calibration/vero-tango-60C.csv"), "cal.json": symlink_to("data.csv")},
               "cal.json", ["cal.json", "data.csv"], "-o a link to DATA: DATA must stay as it was"),
        keep_input("calibrate-plot-symlink-to-input", ["calibrate", "data.csv", "--plot", "fit.png"],
               {"data.csv": copy_of("examples/calibration/vero-tango-60C.csv"), "fit.png": symlink_to("data.csv")},
               "fit.png", ["fit.png", "data.csv"], "--plot a link to DATA: DATA must stay as it was"),
        refuse("calibrate-output-and-plot-same", ["calibrate", "data.csv", "-o", "out", "--plot", "out"],
               {"data.csv": copy_of("examples/calibration/vero-tango-60C.csv")}, ["out"],
               "one file for two outputs: one of them would be lost"),
        refuse("voxelize-output-is-input", ["voxelize", "d.json", "-o", "d.json"], d, ["d.json"], "-o DESIGN"),
        refuse("voxelize-output-is-input-dotslash", ["voxelize", "d.json", "-o", "./d.json"], d, ["d.json"],
               "-o ./DESIGN"),
        keep_input("voxelize-output-symlink-to-input", ["voxelize", "d.json", "-o", "g.vdb"],
               {**d, "g.vdb": symlink_to("d.json")}, "g.vdb", ["g.vdb", "d.json"], "-o a link to DESIGN"),
        refuse("simulate-output-is-input", ["simulate", "m.json", "-o", "m.json"],
               {"m.json": json.dumps(cantilever())}, ["m.json"], "-o DESIGN"),
        refuse("simulate-output-is-input-dotslash", ["simulate", "m.json", "-o", "./m.json"],
               {"m.json": json.dumps(cantilever())}, ["m.json"], "-o ./DESIGN"),
        keep_input("simulate-output-hardlink-to-input", ["simulate", "m.json", "-o", "copy.json"],
               {"m.json": json.dumps(cantilever()), "copy.json": hardlink_to("m.json")}, "copy.json", ["copy.json", "m.json"],
               "-o another name of DESIGN's file (hard link): a write in place would change the design"),
    ]
    # What --force is for: replacing a previous rodfab job, zip or folder.
    longer = design(bar(6.0))
    cs += [
        Case("slice-force-replaces-old-zip-job",
             [Step(["slice", "d.json", "-o", "old.zip", "--force", "--quiet"], outputs=["old.zip"], jobs=["old.zip"],
                   replaces=["old.zip"])],
             files={"d.json": longer, "old.zip": job("zip")}, note="--force over a rodfab zip job"),
        Case("slice-force-replaces-old-dir-job",
             [Step(["slice", "d.json", "-o", "old", "--format", "dir", "--force", "--quiet"], outputs=["old"],
                   jobs=["old"], replaces=["old"])],
             files={"d.json": longer, "old": job("dir")}, note="--force over a rodfab folder job"),
    ]
    return cs
