#!/usr/bin/env python3
"""Writes docs/benchmarks.md (to stdout) from the JSON results scripts/bench.sh leaves in a folder; with
--readme README.md, instead rewrites the README's summary of the same results (between its "make bench"
markers), so that the two never tell different numbers."""

import datetime
import json
import os
import platform
import statistics
import sys

README_START = "<!-- make bench: summary start (scripts/bench_report.py writes this paragraph) -->"
README_END = "<!-- make bench: summary end -->"

STAGES = ["foreground", "filter", "triangulate", "color", "overlap", "redundancy", "clipping", "assemble", "total"]
# Issue 4's time: redundancy removal and clipping added up for each frame set, then the median
# (`zipfusion bench` writes it beside the stages).
REDUNDANCY_PLUS_CLIPPING = "redundancy+clipping"


def load(folder, name):
    path = os.path.join(folder, name)
    if not os.path.exists(path):
        return None
    with open(path) as f:
        return json.load(f)


def run_date(folder, report):
    """When `report` (samba.json) was measured: its own date, or for an older report its file's."""
    if "date" in report:
        return report["date"]
    mtime = os.path.getmtime(os.path.join(folder, "samba.json"))
    return datetime.datetime.fromtimestamp(mtime, datetime.timezone.utc).date().isoformat()


def run_os(report):
    """The kernel the report was measured on; for an older report, this machine's."""
    return report["machine"].get("os", f"{platform.system()} {platform.release()}")


def config(report, name):
    found = optional_config(report, name)
    if found is None:
        sys.exit(f"bench_report: configuration '{name}' missing from the bench results")
    return found


def optional_config(report, name):
    """A configuration that results of an older `zipfusion bench` may lack: None then."""
    return next((c for c in report["configs"] if c["name"] == name), None)


def ms(entry):
    return f"{entry['median']:.1f} / {entry['p95']:.1f}"


def stolen(result):
    """The share of CPU time stolen while a configuration ran, in %, or – where the report predates it."""
    share = result.get("cpu_stolen_share")
    return "–" if share is None else f"{100 * share:.1f}"


def stage_table(report, names):
    lines = ["| stage (ms, median / p95) | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    for stage in STAGES:
        lines.append(f"| {stage} | " + " | ".join(ms(config(report, n)["ms"][stage]) for n in names) + " |")
    # Issue 4's figure, where the results have it: the two zippering stages added per frame set.
    if all(REDUNDANCY_PLUS_CLIPPING in config(report, n)["ms"] for n in names):
        lines.append("| redundancy + clipping, added per frame set | " +
                     " | ".join(ms(config(report, n)["ms"][REDUNDANCY_PLUS_CLIPPING]) for n in names) + " |")
    lines.append("| frames per second | " + " | ".join(f"{config(report, n)['fps']:.1f}" for n in names) + " |")
    lines.append("| triangles | " + " | ".join(f"{config(report, n)['triangles']:.0f}" for n in names) + " |")
    # CPU time the hypervisor gave to other guests while each configuration ran: where it is not
    # small, that column's times are inflated.
    lines.append("| CPU time stolen, % | " + " | ".join(stolen(config(report, n)) for n in names) + " |")
    return lines


def load_rounds(folder, stem):
    """The results of numbered rounds, STEM_1.json, STEM_2.json, ..., up to the first missing one."""
    rounds = []
    for round_number in range(1, 100):
        r = load(folder, f"{stem}_{round_number}.json")
        if r is None:
            break
        rounds.append(r)
    return rounds


def median_and_range(values, digits):
    """The median of per-round figures, and in brackets the lowest and highest round."""
    return f"{statistics.median(values):.{digits}f} ({min(values):.{digits}f}–{max(values):.{digits}f})"


def scaling_section(folder):
    """The scaling table: each rig's totals as the median over the rounds, and the growth against the
    4-camera 640×480 rig taken within each round."""
    rigs = [(f"{n} cameras, 640x480", f"cameras_{n}", n, 640 * 480) for n in (2, 4, 6, 8)]
    # The 640×480 one is the 4-camera rig again, from its own capture: its ratio shows the rounds' noise.
    rigs += [(f"4 cameras, {size}" + (" (the same rig again)" if size == "640x480" else ""), f"size_{size}", 4,
              int(size.split("x")[0]) * int(size.split("x")[1])) for size in ("320x240", "640x480", "1280x960")]
    results = {rig: load_rounds(folder, f"scale_{rig}") for _, rig, _, _ in rigs}
    reference = results["cameras_4"]
    if not reference:
        return []
    rounds = min(len(r) for r in results.values() if r)
    frames = reference[0]["frames"]
    total = lambda r, name: config(r, name)["ms"]["total"]["median"]
    median_total = lambda rig, name: statistics.median(total(r, name) for r in results[rig][:rounds])
    out = ["## Scaling", "", f"Synthetic rigs from `zipfusion synth` ({frames} frames, built-in human, Kinect noise, ring of 2.5 m "
           f"radius), `zipfusion bench --repeat 1` in {rounds} rounds, each round every rig once: total ms, the median over the "
           "frame sets, then over the rounds.", "",
           "What the zipper works on is the cameras' triangles (all of them are the separate meshes') and the overlapping "
           "pairs it finds: more cameras in one ring overlap more (each surface seen twice or more), and a finer depth "
           "image gives more triangles for the same surface. The ns columns divide the zipper's total (every stage, "
           "foreground to assembly) by the cameras' triangles: where they stay flat, the time grows linearly with the work. "
           "The speed-up is the one-thread total over the two-thread one.", "",
           "| rig | zipper | zipper+filter | separate | zipper, 1 thread | CPU time stolen, % (zipper / 1 thread, most of any round) "
           "| overlapping pairs | cameras' triangles | zipper, 1 thread, ns per camera triangle | zipper, all threads, ns per camera triangle "
           "| speed-up of all threads |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for label, rig, _, _ in rigs:
        if not results[rig]:
            continue
        first = results[rig][0]
        camera_triangles = config(first, "separate")["triangles"]
        one_thread = median_total(rig, "zipper 1 thread")
        def most_stolen(name):
            # The round with the most CPU time stolen (one that did not report it counts as least).
            configs = [config(r, name) for r in results[rig][:rounds]]
            return stolen(max(configs, key=lambda c: -1 if c.get("cpu_stolen_share") is None else c["cpu_stolen_share"]))
        pairs = config(first, "zipper").get("pairs")
        all_threads = median_total(rig, "zipper")
        per_triangle = lambda ms: f"{1e6 * ms / camera_triangles:.0f}" if camera_triangles else "–"
        out.append(f"| {label} | {all_threads:.1f} | {median_total(rig, 'zipper+filter'):.1f} | "
                   f"{median_total(rig, 'separate'):.1f} | {one_thread:.1f} | {most_stolen('zipper')} / "
                   f"{most_stolen('zipper 1 thread')} | {'?' if pairs is None else f'{pairs:.0f}'} | {camera_triangles:.0f} | "
                   f"{per_triangle(one_thread)} | {per_triangle(all_threads)} | {one_thread / all_threads:.2f} |")
    # Growth: each rig's time over the 4-camera 640×480 rig's in the same round (median over the
    # rounds), beside the growth of the cameras or pixels and of the cameras' triangles.
    out += ["", "Growth against the 4-camera 640×480 rig, each ratio taken within a round: the median over the rounds, and in "
            "brackets the lowest and highest round. Time proportional to cameras × pixels has their ratio; time linear in them "
            "with a fixed part does not (the table after this one tests that).", "",
            "| rig | cameras × pixels | cameras' triangles | zipper | zipper, 1 thread | zipper+filter |", "|---|---|---|---|---|---|"]
    reference_triangles = config(reference[0], "separate")["triangles"]
    for label, rig, cameras, pixels in rigs:
        if rig == "cameras_4" or not results[rig]:
            continue
        def ratio(name):
            return median_and_range([total(r, name) / total(ref, name) for r, ref in zip(results[rig][:rounds], reference[:rounds])], 2)
        out.append(f"| {label} | {cameras * pixels / (4 * 640 * 480):.2f} | {config(results[rig][0], 'separate')['triangles'] / reference_triangles:.2f} | "
                   f"{ratio('zipper')} | {ratio('zipper 1 thread')} | {ratio('zipper+filter')} |")
    # Linear growth with an intercept (time = fixed + per camera · cameras) has a ratio above the
    # cameras' where the fixed part is negative, as the zipper's is: the redundant triangles it
    # removes are the cameras' triangles less the surface's. The cost of each camera or pixel added
    # stays the same under linear growth, and grows where the growth is faster.
    steps = [("2 → 4 cameras, per camera", "cameras_2", "cameras_4", 2), ("4 → 6 cameras, per camera", "cameras_4", "cameras_6", 2),
             ("6 → 8 cameras, per camera", "cameras_6", "cameras_8", 2),
             ("320x240 → 640x480, per million pixels of each camera", "size_320x240", "cameras_4", (640 * 480 - 320 * 240) / 1e6),
             ("640x480 → 1280x960, per million pixels of each camera", "cameras_4", "size_1280x960", (1280 * 960 - 640 * 480) / 1e6)]
    # The same steps per 100 000 cameras' triangles added: a finer image has more triangles per
    # pixel (fewer are cut at depth steps), so per pixel the work itself grows.
    triangles = lambda rig: config(results[rig][0], "separate")["triangles"] if results[rig] else 0
    steps += [(f"{a} → {b}, per 100 000 cameras' triangles", before, after, (triangles(after) - triangles(before)) / 1e5)
              for a, b, before, after in (("320x240", "640x480", "size_320x240", "cameras_4"), ("640x480", "1280x960", "cameras_4", "size_1280x960"))]
    out += ["", "The same growth as the time each camera, pixel or triangle adds, within each round (ms: the median over the rounds, "
            "and in brackets the lowest and highest round): equal figures down a column mean linear growth.", "",
            "| step | zipper | zipper, 1 thread | zipper+filter |", "|---|---|---|---|"]
    for label, before, after, added in steps:
        if not (results[before] and results[after]) or added <= 0:
            continue
        def step(name):
            return median_and_range([(total(b, name) - total(a, name)) / added for a, b in zip(results[before][:rounds], results[after][:rounds])], 1)
        out.append(f"| {label} | {step('zipper')} | {step('zipper 1 thread')} | {step('zipper+filter')} |")
    out += ["", "Where a triangle costs more at 1280×960 than at 640×480, one count differs: cachegrind (one thread, 32 MB last "
            "level, the zipper alone) counted 4.12 times the instructions for 4.04 times the triangles, but 8.1 times the reads "
            "that miss the last level, as four cameras' buffers at that size no longer fit the cache both cores share. How much "
            "that costs depends on the machine's memory at the time: the per-triangle steps above went from +37 % to −5 % "
            "between two runs of the same code (docs/profile.md, twelfth session of 2026-12-07).", ""]
    return out


def compared(ours, theirs, lower_is_better):
    """'better' or 'worse' (or 'the same') for one quality figure against another."""
    if ours == theirs:
        return "the same"
    return "better" if (ours < theirs) == lower_is_better else "worse"


def readme_summary(folder):
    """The README's paragraph on speed and quality: the same figures as docs/benchmarks.md."""
    samba = load(folder, "samba.json")
    if samba is None:
        sys.exit(f"bench_report: {os.path.join(folder, 'samba.json')}: not found (run scripts/bench.sh)")
    unfiltered, filtered = config(samba, "zipper"), config(samba, "zipper+filter")
    text = (f"For four {samba['depth_size'].replace('x', '×')} Kinect streams, the latest `make bench` (docs/benchmarks.md, "
            f"{run_date(folder, samba)}, {samba['machine']['cpu']}, {samba['machine']['hardware_threads']} hardware "
            f"threads) measured medians of {unfiltered['ms']['total']['median']:.1f} ms per frame set "
            f"({unfiltered['fps']:.1f} fps) without a filter and {filtered['ms']['total']['median']:.1f} ms with the paper's "
            "bilateral filter, at full resolution, in its per-stage table.")
    paired = [(zipfusion, o3d["tsdf"]["total_ms"]["median"])
              for zipfusion, o3d in zip(load_rounds(folder, "paired_zipfusion"), load_rounds(folder, "paired_open3d"))]
    if paired:
        # The per-stage table times each configuration once; the rounds show how far that moves.
        def spread(label):
            totals = [config(z, label)["ms"]["total"]["median"] for z, _ in paired]
            return f"{min(totals):.1f}–{max(totals):.1f} ms (median {statistics.median(totals):.1f})"

        text += (f" In its {len(paired)} alternating rounds the same two took {spread('zipper')} and "
                 f"{spread('zipper+filter')}.")
    tsdf_eval = load(folder, "eval_open3d_block_0.01.json")
    if paired and tsdf_eval:
        tsdf = tsdf_eval["mean"]

        def rounds(label):
            totals = [config(z, label)["ms"]["total"]["median"] for z, _ in paired]
            ratios = [tsdf_ms / config(z, label)["ms"]["total"]["median"] for z, tsdf_ms in paired]
            return (f"{min(totals):.1f}–{max(totals):.1f} ms, {statistics.median(ratios):.2f} times faster than the TSDF "
                    f"(the median of the rounds' ratios; {min(ratios):.2f}–{max(ratios):.2f})")

        def quality(name):
            evaluation = load(folder, f"eval_{name}.json")
            if evaluation is None:
                sys.exit(f"bench_report: {os.path.join(folder, f'eval_{name}.json')}: not found (run scripts/bench.sh)")
            m = evaluation["mean"]
            return (f"{compared(m['accuracy_mean_mm'], tsdf['accuracy_mean_mm'], True)} accuracy "
                    f"({m['accuracy_mean_mm']:.2f} against {tsdf['accuracy_mean_mm']:.2f} mm) and "
                    f"{compared(m['completeness'], tsdf['completeness'], False)} completeness "
                    f"({100 * m['completeness']:.1f} against {100 * tsdf['completeness']:.1f} %)"), m

        five, _ = quality("zipper_bilateral5x5")
        lod, lod_mean = quality("zipper_none_lod1")
        text += (" In those rounds, which alternate with Open3D's tensor TSDF (`VoxelBlockGrid`) at 10 mm, the filter "
                 "over 5×5 pixels instead of the paper's 13×13 (`--bilateral-radius 2 --bilateral-sigma-px 2`) took "
                 f"{rounds('zipper+5x5 filter')}, with {five}. At level of detail 1 without the filter (`--lod 1 --filter none`, every second depth pixel as "
                 f"the mean of its surface around it: {lod_mean['triangles']:.0f} triangles, against the TSDF's "
                 f"{tsdf['triangles']:.0f}) the rounds took {rounds('zipper lod 1')}, with {lod}.")
    return text + " The machine's speed varies by up to a third between minutes (docs/profile.md)."


def rewrite_readme(folder, path):
    """Replaces the paragraph between the README's markers, through a temporary file."""
    try:
        with open(path) as f:
            readme = f.read()
    except OSError as e:
        sys.exit(f"bench_report: {path}: cannot read ({e.strerror})")
    start, end = readme.find(README_START), readme.find(README_END)
    if start < 0 or end < start:
        sys.exit(f"bench_report: {path}: the markers of the make bench summary are missing")
    readme = readme[:start + len(README_START)] + "\n" + readme_summary(folder) + "\n" + readme[end:]
    with open(path + ".tmp", "w") as f:
        f.write(readme)
    os.replace(path + ".tmp", path)


# Zippering's parts as callgrind names them (bench.sh's callgrind_*.txt: callgrind_annotate
# --inclusive=yes), each with its depth in the table and what it does. A part's count is the largest
# inclusive count of a function whose name starts with its prefix, or one of its prefixes (a
# function's lambdas are listed under names that start with its own, but count less). The parts of
# depth 1 do not overlap; what they leave of the whole is "the rest". The window search and memset
# run inside several of them, so they are listed apart.
ZIPPER_WHOLE = ("all of zippering", "zipfusion::zipper_meshes(",
                "`zipper_meshes` on samba-4cam frame 0: four cameras, their overlapping pairs, every step below")
ZIPPER_PARTS = [
    ("ownership score", ("zipfusion::compute_smoothness(", "zipfusion::compute_border_distance("), 1,
     "which camera keeps a surface two cameras see: without the filter each camera's smoothness over a window of 250 "
     "pixels (125 cells of level 1, row kernels); with it, the distance to its mesh's border"),
    ("coarse levels", "zipfusion::downsample_mesh(", 1, "levels 1 and 2 of each camera's triangles, for the coarse-to-fine removal"),
    ("overlap masks", "zipfusion::compute_overlap_mask(", 1,
     "where each pair's meshes come within 2·d_r on the coarsest level: the later steps look only there"),
    ("redundancy removal (FRBR, all levels)", "zipfusion::remove_redundant_boundaries(", 1,
     "boundary triangles tested level by level, sweep after sweep: a projection into the other camera, an ownership test "
     "and, where the other camera owns the surface, a window search"),
    ("taking the seams", "zipfusion::take_seam(", 1,
     "each pair's triangles within d_c of the other mesh along the line where they meet, taken out with their corners and "
     "the kept edges that the seam must keep"),
    ("stitching the seams", "zipfusion::stitch_seam(", 1,
     "each seam's points put on their surfaces and halfway between the two layers, triangulated in 2-D, constrained, "
     "faired and cleared of creases"),
    ("Delaunay insertion", "zipfusion::insert_points(", 2,
     "CGAL's incremental insertion after the seam's hull, each point located from the last one's face, then its flips"),
    ("fairing", "zipfusion::(anonymous namespace)::fair_seam(", 2, "the seam's points smoothed along their rays"),
    ("constraints", "zipfusion::constrain(", 2, "the kept edges made edges of the triangulation: most already are, the rest by flips"),
]
ZIPPER_REST = ("the rest", "pairs found, boundary lists, removals carried to the finer level, assembly, colours")
ZIPPER_ACROSS = [
    ("window search", "zipfusion::has_triangle_near(",
     "inside removal, seams and the finding of pairs: is a triangle centre of the other mesh within a distance of a "
     "projected point, searched cell by cell outwards from it and ended at the first found"),
    ("memset", "memset", "clearing buffers, inside several of the parts"),
]


def callgrind_listing(path):
    """(calls, {function name: largest inclusive instruction count}) from callgrind_annotate's
    listing; calls is the profiled run's --repeat. None where the file is missing."""
    if not os.path.exists(path):
        return None
    calls, counts = None, {}
    with open(path) as f:
        for line in f:
            if line.startswith("Profiled target:"):
                words = line.split()
                if "--repeat" in words:
                    calls = int(words[words.index("--repeat") + 1])
                continue
            fields = line.split(None, 2)
            if len(fields) < 3 or not fields[1].startswith("(") or not fields[0].replace(",", "").isdigit():
                continue
            where = fields[2].rsplit(" [", 1)[0]
            function = where.split(":", 1)[1] if ":" in where else where
            count = int(fields[0].replace(",", ""))
            counts[function] = max(counts.get(function, 0), count)
    if calls is None:
        sys.exit(f"bench_report: {path}: no --repeat in its 'Profiled target' line")
    return calls, counts


def zipper_part_count(counts, prefixes, path):
    if prefixes == "memset":
        return sum(c for name, c in counts.items() if name.startswith("__memset"))
    prefixes = (prefixes,) if isinstance(prefixes, str) else prefixes
    count = max((c for name, c in counts.items() if name.startswith(prefixes)), default=0)
    if count == 0:
        sys.exit(f"bench_report: {path}: no instructions in {' or '.join(prefixes)}")
    return count


def zipper_parts_table(folder):
    """Lines of the table of zippering's parts by instructions in steady state: the run of more calls
    less the run of fewer, per call (the first call also grows the buffers)."""
    runs = []
    for name, depth in [("unfiltered", "unfiltered"), ("the paper's filter", "filtered")]:
        paths = sorted(p for p in os.listdir(folder) if p.startswith(f"callgrind_{depth}_") and p.endswith(".txt"))
        listings = [callgrind_listing(os.path.join(folder, p)) for p in paths]
        if len(listings) != 2:
            return [f"No callgrind results in {folder} (scripts/bench.sh writes them where valgrind is installed).", ""]
        (short_calls, short), (long_calls, long) = sorted(listings, key=lambda listing: listing[0])
        if long_calls <= short_calls:
            sys.exit(f"bench_report: {folder}: callgrind_{depth}_*.txt profile the same number of calls")
        # A function in one listing only would be counted whole or not at all: left out, so a part
        # that needs it stops the report.
        steady = {function: count - short[function] for function, count in long.items() if function in short}
        runs.append((name, long_calls - short_calls, steady, os.path.join(folder, paths[-1])))
    out = ["Inside zippering, by instructions (callgrind, which counts them the same whatever the machine's speed: "
           "`zf_zipper_repeat --capture CAPTURE [--unfiltered] --repeat N --threads 1` under `valgrind --tool=callgrind "
           "--toggle-collect=\"$(zf_zipper_repeat --callgrind-function)\"`, samba-4cam frame 0, N = 6 less N = 3, so that the "
           "first call's growing of buffers is left out; millions of instructions a frame set, and the share of all of "
           "zippering; a part includes what it calls, so the indented parts are inside the one above them):", "",
           "| part | " + " | ".join(name for name, *_ in runs) + " | what it is |", "|---" * (len(runs) + 2) + "|"]

    def cells(prefixes):
        return [zipper_part_count(counts, prefixes, path) for _, _, counts, path in runs]

    totals = cells(ZIPPER_WHOLE[1])

    def row(label, depth, values, what):
        shown = [f"{v / calls / 1e6:.1f} M ({100 * v / t:.0f} %)" for v, t, (_, calls, *_) in zip(values, totals, runs)]
        out.append(f"| {'&nbsp;&nbsp;' * depth}{label} | " + " | ".join(shown) + f" | {what} |")

    row(ZIPPER_WHOLE[0], 0, totals, ZIPPER_WHOLE[2])
    rest = list(totals)
    for label, prefixes, depth, what in ZIPPER_PARTS:
        values = cells(prefixes)
        if depth == 1:
            rest = [r - v for r, v in zip(rest, values)]
        row(label, depth, values, what)
    row(ZIPPER_REST[0], 1, rest, ZIPPER_REST[1])
    for label, prefixes, what in ZIPPER_ACROSS:
        row(f"across the parts: {label}", 1, cells(prefixes), what)
    out.append("")
    return out


def main(folder):
    samba = load(folder, "samba.json")
    if samba is None:
        sys.exit(f"bench_report: {os.path.join(folder, 'samba.json')}: not found (run scripts/bench.sh)")
    out = ["# Benchmarks", "",
           "Written by `make bench` (scripts/bench.sh, then scripts/bench_report.py); raw results in out/bench/.",
           f"Run {run_date(folder, samba)} on {samba['machine']['cpu']}, {samba['machine']['hardware_threads']} hardware threads, "
           f"{run_os(samba)}. Times are wall-clock per frame set, medians and 95th percentiles over "
           f"{samba['frames']} frame sets × {samba['repeat']} passes; decoding is apart from reconstruction.", ""]

    out += ["## Per stage on samba-4cam (the paper's Table IV)", "",
            f"`zipfusion bench ../shared/data/samba-4cam --rig ../shared/data/samba-4cam/ground_truth/rig.json --frames {samba['frames']} "
            f"--repeat {samba['repeat']} --soak {(samba.get('soak') or {}).get('frames', 0)}`: {samba['cameras']} cameras, depth {samba['depth_size']}. "
            f"Decoding the PNG depth and JPEG colour of a frame set (cameras in parallel, into the images of the frame set before, as the pipeline does): {ms(samba['decode_ms'])} ms.", ""]
    out += stage_table(samba, ["zipper+filter", "zipper+separable filter", "zipper+5x5 filter", "zipper", "zipper border ownership",
                               "separate+filter", "separate+5x5 filter", "separate"])
    out += ["", "Without the filter (\"zipper\") ownership is by smoothness, the default there (`--ownership auto`); "
            "\"zipper border ownership\" is the same with `--ownership border`, the default with the filter (docs/design.md). "
            "\"CPU time stolen\" is the share of the machine's CPU time (/proc/stat) that the hypervisor gave to other "
            "guests while the column ran; on a shared virtual machine it inflates the times. \"+5x5 filter\" is the same "
            "bilateral filter over 5×5 pixels with σ 2 px (`--bilateral-radius 2 --bilateral-sigma-px 2`) instead of the "
            "paper's 13×13 with σ 4 px (docs/design.md, *Bilateral filter*).",
            "", "Targets (issue 6): total ≤ 16.7 ms without the filter, ≤ 33 ms with it. Target (issue 4): redundancy removal "
            "+ clipping ≤ 10 ms median per frame set; measured without the filter (\"zipper\"), where the two take longest with "
            "the default options" +
            (": the row \"added per frame set\" is that median; the sum of the two stages' medians is not it."
             if REDUNDANCY_PLUS_CLIPPING in config(samba, "zipper")["ms"] else ".") +
            " The paper's Table IV figures were lost in "
            "the text extraction; its whole pipeline ran at 7.3 fps (137 ms) with CUDA and four threads.", "",
            "At level of detail 1 (`--lod 1`) the same four 640×480 streams are reconstructed from every second depth pixel, "
            "each the mean of the pixels around it on its surface (`subsample_depth`, docs/design.md): a quarter of the "
            "triangles, about as many as Open3D's TSDF at 10 mm gives (Table II below).", ""]
    out += stage_table(samba, ["zipper lod 1", "zipper+filter lod 1"])
    out.append("")
    small, unfiltered = optional_config(samba, "zipper min component 50"), config(samba, "zipper")
    if small:
        out += [f"Dropping the pieces of fewer than 50 triangles after zippering (`--min-component 50`, off by default; "
                f"\"zipper min component 50\", otherwise as \"zipper\"): assembly {ms(small['ms']['assemble'])} ms against "
                f"{ms(unfiltered['ms']['assemble'])}, total {ms(small['ms']['total'])} against {ms(unfiltered['ms']['total'])}, "
                f"{small['triangles']:.0f} triangles against {unfiltered['triangles']:.0f} (quality in Table II below).", ""]

    one = config(samba, "zipper 1 thread")
    two = config(samba, "zipper")
    out += ["## One thread against all (the paper's Table III)", "",
            "| zipper, no filter | total ms (median / p95) | fps | CPU time stolen, % |", "|---|---|---|---|",
            f"| 1 thread | {ms(one['ms']['total'])} | {one['fps']:.1f} | {stolen(one)} |",
            f"| {samba['machine']['hardware_threads']} threads | {ms(two['ms']['total'])} | {two['fps']:.1f} | {stolen(two)} |",
            f"| paper: CUDA + 4 threads, 2011 GPU | 137 | 7.32 | |", ""]

    flat = config(samba, "zipper no coarse-to-fine")
    out += ["## Redundancy removal with and without coarse to fine (the paper's Table V)", "",
            "| | redundancy ms (median / p95) | total ms |", "|---|---|---|",
            f"| coarse to fine (L = 2) | {ms(two['ms']['redundancy'])} | {two['ms']['total']['median']:.1f} |",
            f"| full resolution only (L = 0) | {ms(flat['ms']['redundancy'])} | {flat['ms']['total']['median']:.1f} |",
            "| paper, without coarse to fine | > 100 | |", ""]

    out += ["## Quality and time side by side, and Open3D (the paper's Table II)", "",
            f"`zipfusion reconstruct` then `zipfusion eval` on frames 0–{samba['frames'] - 1} with the true poses; zipfusion's "
            "times are `zipfusion bench`'s medians above. Open3D (Debian's libopen3d-dev) runs through `zf_open3d_compare` "
            "(bench/open3d_compare.cc, built when CMake finds Open3D; never linked into the library or `zipfusion`):", "",
            "- *Same input*: each camera's depth after zipfusion's own `extract_foreground` (0.4–4.5 m, capture volume), as "
            "float metres; colour resampled into the depth camera as `lookup_colors` does. That preparation is ours and not "
            "in Open3D's time; meshes lose the triangles outside the volume (`eval` ignores those anyway).",
            "- *TSDF*: a fresh `ScalableTSDFVolume` per frame set (voxel 10 or 5 mm, truncation 4 voxels, RGB8 colour, "
            "Open3D's defaults otherwise), every camera integrated with camera_from_world = world_from_depth⁻¹, then "
            "`ExtractTriangleMesh`; time = integrate + extract.",
            "- *Tensor TSDF* (`--tsdf voxel-block-grid`): Open3D's `t::geometry::VoxelBlockGrid` on the CPU device (blocks "
            "of 16³ voxels, float TSDF, weight and colour; depth as uint16 millimetres, colour as uint8), the same voxel "
            "and truncation. One grid is made before the first frame set (making one zeroes its whole buffer: about "
            "190 ms) and cleared for each, the weights of the blocks a frame set activates zeroed first (Open3D leaves a "
            "reactivated block's old voxels); time = clearing + zeroing + integrate + extract (weight > 0, as the legacy "
            "volume). The ratio column is against the faster of the two TSDFs at 10 mm.",
            "- *Poisson* (frame 0 only): all cameras' foreground points merged, normals from 30 neighbours flipped towards "
            "the camera that saw them, `CreateFromPointCloudPoisson` depth 8, no density trimming; time = normals + Poisson.",
            "- *Threads*: both use all cores; Open3D's OpenMP runs with `OMP_WAIT_POLICY=PASSIVE` (spin-waiting made it "
            "several times slower on a shared machine).", "",
            "| method | ms per frame set | × faster Open3D TSDF 10 mm | accuracy mm (mean / p95) | completeness % | area ratio | "
            "large comps (all) | triangles |",
            "|---|---|---|---|---|---|---|---|"]
    rows = []
    timing = {"zipper_bilateral": "zipper+filter", "zipper_bilateral5x5": "zipper+5x5 filter", "zipper_none": "zipper",
              "zipper_bilateral_lod1": "zipper+filter lod 1", "zipper_none_lod1": "zipper lod 1", "separate_bilateral": "separate+filter",
              "separate_bilateral5x5": "separate+5x5 filter", "separate_none": "separate",
              "zipper_none_min50": "zipper min component 50"}
    for name, label in timing.items():
        evaluation = load(folder, f"eval_{name}.json")
        # The min-component configuration is newer than some bench results: only it may be missing.
        timed = optional_config(samba, label) if name == "zipper_none_min50" else config(samba, label)
        if evaluation and timed:
            rows.append((f"zipfusion {label}", evaluation, timed["ms"]["total"]["median"]))
    tsdf_10mm = []
    for volume, prefix in [("ScalableTSDFVolume", "open3d_"), ("VoxelBlockGrid", "open3d_block_")]:
        for voxel in ["0.01", "0.005"]:
            o3d, evaluation = load(folder, f"{prefix}{voxel}.json"), load(folder, f"eval_{prefix}{voxel}.json")
            if o3d and evaluation:
                rows.append((f"Open3D TSDF {float(voxel) * 1000:.0f} mm ({volume})", evaluation, o3d["tsdf"]["total_ms"]["median"]))
                if voxel == "0.01":
                    tsdf_10mm.append(o3d["tsdf"]["total_ms"]["median"])
    o3d, poisson = load(folder, "open3d_0.01.json"), load(folder, "eval_poisson.json")
    if o3d and poisson and "poisson" in o3d:
        rows.append(("Open3D Poisson depth 8 (frame 0)", poisson, o3d["poisson"]["ms"]["total"]))
    reference = min(tsdf_10mm) if tsdf_10mm else None
    for label, evaluation, time in rows:
        m = evaluation["mean"]
        speed = f"{reference / time:.2f}" if reference else "–"
        out.append(f"| {label} | {time:.1f} | {speed} | {m['accuracy_mean_mm']:.2f} / {m['accuracy_p95_mm']:.2f} | "
                   f"{100 * m['completeness']:.1f} | {m['area_ratio']:.2f} | {m['large_components']:.1f} ({m['components']:.0f}) | "
                   f"{m['triangles']:.0f} |")
    out += ["", "Target (issue 6): zipfusion ≥ 5× faster than Open3D TSDF at 10 mm (here the faster of its two volumes), with "
            "better accuracy and completeness. "
            "The paper reports Poisson reconstruction taking seconds per frame.", ""]

    paired = [(zipfusion, o3d["tsdf"]["total_ms"]["median"])
              for zipfusion, o3d in zip(load_rounds(folder, "paired_zipfusion"), load_rounds(folder, "paired_open3d"))]
    if paired:
        labels = ["zipper+5x5 filter", "zipper", "zipper+filter", "zipper lod 1"]
        out += ["### The same ratios in alternating rounds", "",
                f"The machine's speed changes by up to a third from minute to minute, and the table above times each method "
                f"once, minutes apart. Here `zipfusion bench --frames {samba['frames']} --repeat 1` and Open3D's tensor TSDF at "
                f"10 mm (`zf_open3d_compare --tsdf voxel-block-grid`) alternate in {len(paired)} rounds; each ratio is taken "
                "within its round (ms per frame set, medians over the frame sets).", "",
                "| round | Open3D tensor TSDF 10 mm | " + " | ".join(f"{label} (× TSDF)" for label in labels) + " |",
                "|---|---|" + "---|" * len(labels)]
        ratios = {label: [] for label in labels}
        for k, (zipfusion, tsdf_ms) in enumerate(paired, 1):
            cells = []
            for label in labels:
                total = config(zipfusion, label)["ms"]["total"]["median"]
                ratios[label].append(tsdf_ms / total)
                cells.append(f"{total:.1f} ({tsdf_ms / total:.2f})")
            out.append(f"| {k} | {tsdf_ms:.1f} | " + " | ".join(cells) + " |")
        out.append("| median ratio | | " + " | ".join(f"{statistics.median(ratios[label]):.2f}" for label in labels) + " |")
        out.append("")
        together = [config(z, "zipper")["ms"].get(REDUNDANCY_PLUS_CLIPPING) for z, _ in paired]
        if all(together):
            medians = [t["median"] for t in together]
            out += [f"Issue 4's redundancy removal + clipping (zipper, without the filter; the two stages added per frame set, "
                    f"then the median over the frame sets), in the same rounds: " + ", ".join(f"{m:.2f}" for m in medians) +
                    f" ms; median {statistics.median(medians):.2f} ms, {sum(m > 10 for m in medians)} of {len(medians)} "
                    "over the target of 10 ms.", ""]

    out += scaling_section(folder)

    if samba.get("soak"):
        s = samba["soak"]
        out += ["## Memory", "", f"Resident memory while reconstructing {s['frames']} frame sets in a row (zipper+filter): "
                f"{s['rss_mb_early']:.0f} MB after {s['early_frames']}, {s['rss_mb_at_end']:.0f} MB after {s['frames']}; "
                f"peak {samba['peak_rss_mb']:.0f} MB.", ""]

    clients, one, flow, browser, draco = (load(folder, f"stream_{n}.json") for n in ("clients", "one_client", "flow_client", "browser", "draco"))
    if clients and draco:
        out += ["## The live stream (issue 8)", "",
                "`zipfusion serve` on samba-4cam (true poses, level of detail 1, Draco 11-bit positions, "
                f"compression level {draco.get('compression_level', 4)}), "
                "looping at 30 fps; clients on the same machine (loopback).", "",
                "| Draco, 4-camera frame set (mean over the frames) | level of detail 0 (full depth) | level of detail 1 (the stream's) |",
                "|---|---|---|",
                f"| triangles | {draco['lod0']['triangles']:.0f} | {draco['lod1']['triangles']:.0f} |",
                f"| compressed, kB | {draco['lod0']['kb']:.1f} | {draco['lod1']['kb']:.1f} |",
                f"| Mbit/s at 30 fps | {draco['lod0']['kb'] * 8 * 30 / 1000:.1f} | {draco['lod1']['kb'] * 8 * 30 / 1000:.1f} |",
                f"| encoding, ms (median) | {draco['lod0']['encode_ms']:.1f} | {draco['lod1']['encode_ms']:.1f} |",
                f"| largest position error / bound, mm | {draco['lod0']['max_error_mm']:.2f} / {draco['bound_mm']:.2f} | "
                f"{draco['lod1']['max_error_mm']:.2f} / {draco['bound_mm']:.2f} |", "",
                "| viewers | frames/s per reading viewer (min–max) | capture → arrival latency, ms (median / p95) | kB per frame |",
                "|---|---|---|---|"]
        for label, r in (("1", one), ("1, flow window of 3 (the viewer's), acknowledging each frame on arrival", flow),
                         (f"{clients['clients']} ({clients['stalled']} stalled)", clients)):
            if r:
                out.append(f"| {label} | {r['reader_fps_min']:.1f}–{r['reader_fps_max']:.1f} | {r['latency_ms_median']:.1f} / {r['latency_ms_p95']:.1f} | "
                           f"{r['frame_kb_mean']:.1f} |")
        if browser:
            out += ["", f"In headless Chromium (Debian's, software WebGL: this machine has no GPU) on the same two cores as the server: "
                    f"capture → drawn latency {browser['latency_ms_median']:.0f} ms (median of the viewer's own median over "
                    f"{browser['samples']} readings), drawing {browser['fps_median']:.1f} frames/s (`node bench/stream_latency.mjs URL`)."]
        out.append("")

    kernels = [load(folder, name) for name in ("kernels.json", "micro.json")]
    if any(kernels):
        out += ["## Kernels (Google Benchmark: `zf_kernel_bench` on samba-4cam frame 0, one camera; `zf_micro_bench`)", "",
                "| kernel | ms (median of 5 runs) |", "|---|---|"]
        for result in filter(None, kernels):
            for b in result["benchmarks"]:
                if b.get("aggregate_name") == "median":
                    # Each benchmark reports in its own unit (Unit(...)); the table is in ms.
                    to_ms = {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}[b.get("time_unit", "ns")]
                    out.append(f"| {b['run_name']} | {b['real_time'] * to_ms:.3f} |")
        out.append("")

    # Each stage's share of the sum of the stages' medians (the total's median is not their sum).
    names = ["zipper", "zipper+5x5 filter"]
    out += ["## Where the time goes", "",
            "Each stage's share of the sum of the stages' medians in the per-stage table on samba-4cam (rounded, so a column "
            "may not add to exactly 100 %):", "",
            "| stage | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    sums = {n: sum(config(samba, n)["ms"][stage]["median"] for stage in STAGES[:-1]) for n in names}
    for stage in STAGES[:-1]:
        out.append(f"| {stage} | " + " | ".join(f"{100 * config(samba, n)['ms'][stage]['median'] / sums[n]:.0f} %" for n in names) + " |")
    out += [""] + zipper_parts_table(folder)
    out += ["More in [profile.md](profile.md): `perf` and callgrind profiles taken apart from this run (per function and per "
            "source line), instruction counts per rig, and every idea measured towards the targets, kept or not, with an "
            "index of them at its top.", ""]
    print("\n".join(out))


if __name__ == "__main__":
    arguments = sys.argv[1:]
    if len(arguments) == 3 and arguments[1] == "--readme":
        rewrite_readme(arguments[0], arguments[2])
    elif len(arguments) <= 1:
        main(arguments[0] if arguments else "out/bench")
    else:
        sys.exit("usage: bench_report.py [FOLDER] | FOLDER --readme README.md")
