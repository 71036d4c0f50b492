#!/usr/bin/env python3
"""Check the #include structure of the cslam tree (Python 3 standard library only).

Usage: check-includes.py [ROOT] [--list-floors]     (ROOT defaults to the repository root)

Every #include in src/, client/, server/, proto/, tools/ and tests/ is resolved the way the
compiler would: first next to the including file, then against src/, the repository root and the
other include roots the CMakeLists.txt files declare (target_include_directories with
${CMAKE_SOURCE_DIR}/... or ${CMAKE_CURRENT_SOURCE_DIR}, e.g. tests/ and tools/experiment/).

Rules (a violation is printed as "file:line: #include ...  [rule] why"; exit status 1):
 1 floors   src/ is layered in FLOORS (lowest first), each floor a set of folders relative to src/.
            A file's folder is the longest declared folder that prefixes its path
            (src/slam/map/x.h is in slam/map, src/slam/client_slam.h in slam). A file in folder F
            may include headers of F itself and of folders on LOWER floors only: never a higher
            floor, never a sibling on the same floor, except the commented ALLOWANCES below.
            Headers are written as "folder/file.h" relative to src/ (not "x.h", not "../x.h").
            SUPPORT folders (src/support/*) sit beside the floors: they may include only
            SUPPORT_MAY_INCLUDE and themselves, and nothing else in src/ may include them.
            Every src/ folder holding code must be declared exactly (a new folder is not silently
            folded into its parent's floor), and every declared folder must hold code.
 2 src-deps nothing in src/ includes ZeroMQ (zmq.h, zmq.hpp), protobuf (google/protobuf/..., *.pb.h)
            or HTTP (httplib.h), nor any header of proto/, server/, client/ or tests/.
 3 client   nothing in client/ includes server/ or tests/ headers.
 4 tests    no production code (src/, server/, client/, proto/, tools/) includes a header that
            lives under tests/ (however it is spelt: "../../tests/x.h", or "optimize/fixtures.h"
            found through a tests/ include directory).
 5 stale    a quoted include that resolves to no file in the tree is an error (stale path),
            except generated protobuf headers (*.pb.h) and the THIRD_PARTY_QUOTED names.
"""
import argparse
import os
import re
import sys

# Floors of src/, lowest first. Derived from the includes and each folder's CMakeLists.txt DEPS;
# the CMake graph alone is not a clean source (io includes frame/ without listing cslam_frame,
# dense includes slam/map/keyframe_pose.h without cslam_map, features <-> bow), so it is declared.
FLOORS = [
    {"core"},
    {"geometry", "codec"},
    {"frame"},                      # header-only input/result types (codec + geometry)
    {"io", "cloud", "optimize"},    # io/dataset_frame.h carries a frame/RgbdFrame
    {"eval"},                       # reads trajectories through io/
    {"slam/features"},
    {"slam/bow"},
    {"slam/map"},
    {"slam/match"},
    {"slam/tracking"},
    {"slam/loop"},
    {"slam/mapping"},               # local mapping includes slam/tracking
    {"slam"},                       # root files of src/slam: ClientSlam wires the stages
    {"fusion"},
    {"dense"},
    {"navmap"},
    {"system"},
]
# Support libraries for tools, tests and benchmarks: beside the floors, not part of the library.
SUPPORT = {"support/synth", "support/report", "support/problems"}
SUPPORT_MAY_INCLUDE = {"core", "geometry", "codec", "frame", "io", "cloud", "eval"}
# Beyond that, per support folder: the synthetic optimisation problems are built for the optimisers.
SUPPORT_ALSO = {"support/problems": {"optimize"}}
# Explicit exceptions to rule 1: (including folder, included header relative to src/) -> reason.
ALLOWANCES = {
    # bow_vector.h is header-only (two boost::flat_map aliases) so that BoW-accelerated matching
    # in features/matching.h can use it without linking cslam_bow (see its header comment).
    ("slam/features", "slam/bow/bow_vector.h"): "header-only BoW types used by matching",
}
FORBIDDEN_IN_SRC = re.compile(r"(^|/)(zmq\.h|zmq\.hpp|zmq_addon\.hpp|httplib\.h)$"
                              r"|^google/protobuf/|\.pb\.h$")
NON_LIBRARY = ("proto", "server", "client", "tests")
PRODUCTION = ("src", "server", "client", "proto", "tools")
SCANNED = PRODUCTION + ("tests",)
THIRD_PARTY_QUOTED = set()  # quoted third-party headers that are not in the tree (none today)
EXTS = (".h", ".hh", ".hpp", ".hxx", ".inl", ".ipp", ".c", ".cc", ".cpp", ".cxx")
SKIP_DIRS = {"build", "third_party", "node_modules", ".git", "__pycache__"}
INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^">]+)[">]')
CMAKE_INCDIR = re.compile(r"target_include_directories\s*\(([^)]*)\)", re.S)


def source_files(root, top):
    for d, dirs, files in os.walk(os.path.join(root, top)):
        dirs[:] = sorted(x for x in dirs if x not in SKIP_DIRS and not x.startswith("build"))
        for f in sorted(files):
            if f.endswith(EXTS):
                yield os.path.relpath(os.path.join(d, f), root).replace(os.sep, "/")


def include_roots(root):
    """src/ and the root first, then every in-tree directory a CMakeLists.txt adds as include dir."""
    roots = ["src", "."]
    for top in SCANNED:
        for d, dirs, files in os.walk(os.path.join(root, top)):
            dirs[:] = sorted(x for x in dirs if x not in SKIP_DIRS)
            if "CMakeLists.txt" not in files:
                continue
            text = open(os.path.join(d, "CMakeLists.txt"), errors="replace").read()
            here = os.path.relpath(d, root)
            for args in CMAKE_INCDIR.findall(text):
                for tok in args.split():
                    tok = tok.replace("${CMAKE_CURRENT_SOURCE_DIR}", here)
                    tok = tok.replace("${CMAKE_SOURCE_DIR}", ".")
                    if "$" in tok or tok.isupper():  # binary dirs, PUBLIC/PRIVATE/...
                        continue
                    rel = os.path.normpath(tok).replace(os.sep, "/")
                    if os.path.isdir(os.path.join(root, rel)) and rel not in roots:
                        roots.append(rel)
    return roots


def resolve(root, roots, including, inc):
    """Path (relative to root) of the file `inc` names, or None if it is not in the tree."""
    for base in [os.path.dirname(including)] + roots:
        cand = os.path.normpath(os.path.join(base, inc)).replace(os.sep, "/")
        if not cand.startswith("../") and os.path.isfile(os.path.join(root, cand)):
            return cand
    return None


def src_folders(root):
    """Folders of src/ (relative to src/) that directly hold code."""
    found = set()
    for path in source_files(root, "src"):
        found.add(os.path.dirname(path)[len("src/"):])
    return found


def folder_of(path_in_src, declared):
    """Longest declared folder that prefixes path_in_src (a path relative to src/)."""
    best = None
    for f in declared:
        if path_in_src.startswith(f + "/") and (best is None or len(f) > len(best)):
            best = f
    return best


def check_file(root, roots, path, floor, declared, out):
    top = path.split("/", 1)[0]
    lines = open(os.path.join(root, path), errors="replace").read().splitlines()
    for n, line in enumerate(lines, 1):
        m = INCLUDE.match(line)
        if not m:
            continue
        quoted, inc = m.group(1) == '"', m.group(2).strip()
        # <a/b.h> is looked up in the include roots only; <vector> etc. never resolve.
        target = resolve(root, roots, path if quoted else "", inc) if quoted or "/" in inc else None
        where = "%s:%d: #include %s" % (path, n, m.group(1) + inc + ('"' if quoted else ">"))
        before = len(out)

        def bad(rule, why):
            out.append("%s  [%s] %s" % (where, rule, why))

        names_tests = target is not None and target.startswith("tests/")
        names_tests = names_tests or re.search(r"(^|/)tests/", inc) is not None
        if top in PRODUCTION and names_tests:
            bad("4 tests", "production code must not include test headers")
        if top == "client" and (inc.startswith("server/") or (target or "").startswith("server/")):
            bad("3 client", "client/ must not include server/ headers")
        if top == "src":
            if FORBIDDEN_IN_SRC.search(inc):
                bad("2 src-deps", "src/ must not depend on ZeroMQ, protobuf or HTTP")
                continue
            tgt_top = (target or inc).split("/", 1)[0]
            if tgt_top in NON_LIBRARY and not names_tests:
                bad("2 src-deps", "src/ must not include %s/ headers" % tgt_top)
                continue
        if target is None:
            stale = quoted and not inc.endswith(".pb.h") and inc not in THIRD_PARTY_QUOTED
            if stale and len(out) == before:  # not already reported for another rule
                bad("5 stale", "no such file in the tree")
            continue
        if top == "src" and target.startswith("src/"):
            check_floor(path[4:], target[4:], inc, floor, declared, bad)


def check_floor(src_path, tgt_path, inc, floor, declared, bad):
    me, it = folder_of(src_path, declared), folder_of(tgt_path, declared)
    if me is None or it is None:
        return  # undeclared folders are reported once, by main()
    if inc != tgt_path:
        bad("1 floors", 'write it relative to src/: "%s"' % tgt_path)
    if me == it or (me, tgt_path) in ALLOWANCES:
        return
    if me in SUPPORT:
        if it not in SUPPORT_MAY_INCLUDE | SUPPORT_ALSO.get(me, set()):
            bad("1 floors", "support folder %s may include only %s"
                % (me, ", ".join(sorted(SUPPORT_MAY_INCLUDE | SUPPORT_ALSO.get(me, set())))))
    elif it in SUPPORT:
        bad("1 floors", "library folder %s must not include support folder %s" % (me, it))
    elif floor[it] == floor[me]:
        bad("1 floors", "%s and %s are siblings on floor %d" % (me, it, floor[me]))
    elif floor[it] > floor[me]:
        bad("1 floors", "%s (floor %d) includes the higher %s (floor %d)"
            % (me, floor[me], it, floor[it]))


def list_floors():
    for i, folders in enumerate(FLOORS):
        print("floor %2d: %s" % (i, ", ".join(sorted(folders))))
    print("support : %s  (may include: %s)"
          % (", ".join(sorted(SUPPORT)), ", ".join(sorted(SUPPORT_MAY_INCLUDE))))
    for (who, hdr), why in sorted(ALLOWANCES.items()):
        print("allowed : %s -> %s  (%s)" % (who, hdr, why))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("root", nargs="?",
                    default=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    ap.add_argument("--list-floors", action="store_true", help="print the floors and exit")
    args = ap.parse_args()
    if args.list_floors:
        list_floors()
        return 0
    root = os.path.abspath(args.root)
    if not os.path.isdir(os.path.join(root, "src")):
        print("check-includes: %s has no src/" % root, file=sys.stderr)
        return 2

    floor = {f: i for i, fs in enumerate(FLOORS) for f in fs}
    declared = set(floor) | SUPPORT
    out = []
    present = src_folders(root)
    for f in sorted(present):
        if f not in declared:
            out.append("src/%s: folder is on no floor: declare it in %s"
                       % (f, os.path.basename(__file__)))
    for f in sorted(declared):
        if not any(p == f or p.startswith(f + "/") for p in present):
            out.append("src/%s: declared folder holds no code: remove it from the floors" % f)

    roots = include_roots(root)
    count = 0
    for top in SCANNED:
        for path in source_files(root, top):
            count += 1
            check_file(root, roots, path, floor, declared, out)

    if out:
        print("check-includes: %d violation(s) in %d files under %s:" % (len(out), count, root))
        for row in out:
            print(row)
        print("(rules: see the docstring of scripts/check-includes.py; floors: --list-floors)")
        return 1
    print("check-includes: OK (%d files, %d floors, include roots: %s)"
          % (count, len(FLOORS), ", ".join(roots)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
