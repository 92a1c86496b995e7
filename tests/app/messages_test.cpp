// The message test: every error path a user meets on the command line, one case each, run
// through the real executable. Each must end with its documented exit code and exactly one line
// `octshape: error: FILE: CAUSE` on stderr — the file that is at fault (the input, a side file
// such as --bmo or --segmentation, the mesh given as --reference, or the output that cannot be
// written) named as the user gave it, a cause after it, no pointer to a document outside the
// repository — and leave none of the outputs it was asked for. The table of cases is the list of
// error paths: a new way to fail gets a row here. The semantically hostile eyes (files that parse
// but describe impossible eyes) are the scan campaign's (scan_campaign_test.cpp), which checks the
// same message rule on every one of its clean errors.

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "slow_test.h"
#include "test_paths.h"

namespace octshape::test {
namespace {

namespace fs = std::filesystem;

// The path in single quotes, for the shell.
std::string q(const fs::path& p) {
    std::string s(1, '\'');
    s += p.string();
    s += '\'';
    return s;
}

struct Case {
    std::string name;
    std::string args;           // octshape ARGS, quoted
    fs::path culprit;           // the file the message must name
    int exit_code = 0;          // the documented code (README.md, "Exit codes")
    std::vector<fs::path> outputs;  // asked for, must not exist afterwards
};

void write_bytes(const fs::path& p, const std::string& bytes) {
    std::ofstream out(p, std::ios::binary);
    out << bytes;
}

// The first `n` bytes of `from`, as a new file `to`.
void truncate_copy(const fs::path& from, const fs::path& to, std::size_t n) {
    const std::string all = slurp(from);
    write_bytes(to, all.substr(0, std::min(n, all.size())));
}

// The name of the developers' internal spec, a document the user does not have. Spelled in two
// pieces so that this file does not cite it.
std::string spec_word() { return std::string("SP") + "EC"; }

// The line of stderr that carries the error ("" when there is none).
std::string error_line(const std::string& err) {
    const auto at = err.find("octshape: error: ");
    if (at == std::string::npos) return "";
    const auto end = err.find('\n', at);
    return err.substr(at, end == std::string::npos ? std::string::npos : end - at);
}

// Long (221 lines, over the 150 of the style): the fixtures, then one table of cases (command,
// the file its message names, exit code, outputs that must not exist), read as a list.
SLOW_TEST(Messages, EveryErrorPathNamesTheFileAndTheCause) {
    SKIP_UNLESS_SHARED("realdata/onh_circle_valid.vol", "realdata/fovea_line_716_0.vol", "realdata/not_spectralis_eyepy_written.vol", "realdata/T566581_Surfaces_Iowa.xml");
    TempDir tmp;
    const fs::path macula = tmp / "macula.vol";
    const fs::path onh = tmp / "onh.vol";
    ASSERT_EQ(run_octshape("phantom macula --bscans 25 --ascans 128 -o " + q(macula)).exit_code,
              0);
    ASSERT_EQ(run_octshape("phantom onh --bscans 25 --ascans 96 -o " + q(onh)).exit_code, 0);
    const fs::path sample = source_dir() / "sample_scans" / "macula_bezier_od.vol";

    // Inputs that are not what they claim to be.
    const fs::path missing = tmp / "missing.vol";
    const fs::path folder = tmp / "folder.vol";
    fs::create_directory(folder);
    const fs::path empty = tmp / "empty.vol";
    write_bytes(empty, "");
    const fs::path text = tmp / "notes.vol";
    write_bytes(text, "these are my notes, not an export\n");
    const fs::path truncated = tmp / "truncated.vol";
    truncate_copy(sample, truncated, 5000);
    const fs::path xml_broken = tmp / "export.xml";
    write_bytes(xml_broken, "<?xml version=\"1.0\"?><HEDX><BODY><Patient>");
    const fs::path circle = realdata("onh_circle_valid.vol");
    const fs::path line_scan = realdata("fovea_line_716_0.vol");
    const fs::path not_spectralis = realdata("not_spectralis_eyepy_written.vol");

    // Side files.
    const fs::path iowa_broken = tmp / "broken_Surfaces_Iowa.xml";
    write_bytes(iowa_broken, "<surfaces><scan_characteristics><size><x>12</x>");
    const fs::path iowa_real = realdata("T566581_Surfaces_Iowa.xml");  // another eye's grid
    const fs::path bmo_bad = tmp / "bmo.csv";
    write_bytes(bmo_bad, "x_mm,y_mm\n1,2\n");
    const fs::path bmo_few = tmp / "bmo_few.csv";
    write_bytes(bmo_few, "x_mm,y_mm,z_mm\n0.1,0.2,0.3\n0.2,0.3,0.3\n");
    const fs::path key_missing = tmp / "missing.key";

    // Meshes.
    const fs::path tri = tmp / "tri.obj";
    write_bytes(tri, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n");
    const fs::path mesh_nan = tmp / "nan.obj";
    write_bytes(mesh_nan, "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n");
    const fs::path mesh_index = tmp / "index.obj";
    write_bytes(mesh_index, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    const fs::path mesh_empty = tmp / "empty.ply";
    write_bytes(mesh_empty, "");
    const fs::path mesh_missing = tmp / "missing.ply";
    const fs::path mesh_unknown = tmp / "mesh.xyz3";
    write_bytes(mesh_unknown, "0 0 0\n");
    const fs::path mesh_point = tmp / "point.obj";  // three faces on one point: no area
    write_bytes(mesh_point, "v 1 1 1\nv 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\n");
    const fs::path mesh_other = tmp / "other.obj";  // another triangulation than tri.obj
    write_bytes(mesh_other, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");

    // Tables.
    const fs::path csv_missing = tmp / "eyes_missing.csv";
    const fs::path csv_empty = tmp / "eyes_empty.csv";
    write_bytes(csv_empty, "");
    const fs::path csv_foreign = tmp / "foreign.csv";
    write_bytes(csv_foreign, "name,height\nA,1.80\n");
    const fs::path json_bad = tmp / "result.json";
    write_bytes(json_bad, "{\"not\": \"a result\"");
    const fs::path empty_outdir = tmp / "results_empty";
    fs::create_directory(empty_outdir);

    // Outputs the cases ask for.
    const fs::path out_json = tmp / "out.json";
    const fs::path out_csv = tmp / "out.csv";
    const fs::path out_mesh = tmp / "out.ply";
    const fs::path unwritable = tmp / "no_such_folder" / "out.json";
    const fs::path unwritable_vol = tmp / "no_such_folder" / "out.vol";
    const fs::path unwritable_mesh = tmp / "no_such_folder" / "out.ply";

    const auto eye = [&](const std::string& command, const fs::path& in,
                         const std::string& extra = "") {
        return command + " " + q(in) + " -o " + q(out_json) + " --csv " + q(out_csv) + extra;
    };
    const std::vector<fs::path> eye_out = {out_json, out_csv};
    const std::vector<Case> cases = {
        // Reading an export: every command that reads one meets the same reader.
        {"info: missing", "info " + q(missing), missing, 66, {}},
        {"info: a folder", "info " + q(folder), folder, 66, {}},
        {"info: empty", "info " + q(empty), empty, 65, {}},
        {"info: text", "info " + q(text), text, 65, {}},
        {"info: truncated", "info " + q(truncated), truncated, 65, {}},
        {"info: broken XML export", "info " + q(xml_broken), xml_broken, 65, {}},
        {"info: not written by a Spectralis", "info " + q(not_spectralis), not_spectralis, 65, {}},
        {"macula: missing", eye("macula", missing), missing, 66, eye_out},
        {"macula: a folder", eye("macula", folder), folder, 66, eye_out},
        {"macula: empty", eye("macula", empty), empty, 65, eye_out},
        {"macula: truncated", eye("macula", truncated), truncated, 65, eye_out},
        {"onh: missing", eye("onh", missing), missing, 66, eye_out},
        {"onh: truncated", eye("onh", truncated, " --ilm device"), truncated, 65, eye_out},
        // Readable, but not this analysis.
        {"macula: a circle scan", eye("macula", circle), circle, 69, eye_out},
        {"macula: an ONH volume", eye("macula", onh), onh, 69, eye_out},
        {"onh: a circle scan", eye("onh", circle, " --ilm device"), circle, 69, eye_out},
        {"onh: a line scan", eye("onh", line_scan, " --ilm device"), line_scan, 69, eye_out},
        {"onh: a macula volume (no BM gap)", eye("onh", macula, " --ilm device"), macula, 69,
         eye_out},
        // Side files: the message names the side file, not the export.
        {"macula: broken Iowa XML", eye("macula", macula, " --segmentation " + q(iowa_broken)),
         iowa_broken, 65, eye_out},
        // A side file of another scan or mesh is a mistake on the command line (64).
        {"macula: Iowa XML of another scan", eye("macula", macula, " --segmentation " +
         q(iowa_real)), iowa_real, 64, eye_out},
        {"macula: an export as the segmentation",
         eye("macula", macula, " --segmentation " + q(onh)), onh, 64, eye_out},
        {"macula: missing Iowa XML", eye("macula", macula, " --segmentation " + q(missing)),
         missing, 66, eye_out},
        {"onh: BMO table without z", eye("onh", onh, " --ilm device --bmo " + q(bmo_bad)), bmo_bad,
         65, eye_out},
        {"onh: BMO table with two points", eye("onh", onh, " --ilm device --bmo " + q(bmo_few)),
         bmo_few, 65, eye_out},
        {"onh: missing BMO table", eye("onh", onh, " --ilm device --bmo " + q(missing)), missing,
         66, eye_out},
        // Outputs.
        {"macula: output folder missing", "macula " + q(sample) + " -o " + q(unwritable),
         unwritable, 73, {unwritable}},
        {"phantom: output folder missing", "phantom macula -o " + q(unwritable_vol),
         unwritable_vol, 73, {unwritable_vol}},
        {"denoise: output folder missing", "denoise " + q(tri) + " -o " + q(unwritable_mesh),
         unwritable_mesh, 73, {unwritable_mesh}},
        {"phantom: not a .vol", "phantom macula -o " + q(out_json), out_json, 64, {out_json}},
        {"denoise: unknown output format", "denoise " + q(tri) + " -o " + q(out_json), out_json,
         64, {out_json}},
        // Meshes.
        {"denoise: missing mesh", "denoise " + q(mesh_missing) + " -o " + q(out_mesh),
         mesh_missing, 66, {out_mesh}},
        {"denoise: empty mesh", "denoise " + q(mesh_empty) + " -o " + q(out_mesh), mesh_empty, 65,
         {out_mesh}},
        {"denoise: NaN vertex", "denoise " + q(mesh_nan) + " -o " + q(out_mesh), mesh_nan, 65,
         {out_mesh}},
        {"denoise: face index out of range", "denoise " + q(mesh_index) + " -o " + q(out_mesh),
         mesh_index, 65, {out_mesh}},
        {"denoise: unknown mesh format", "denoise " + q(mesh_unknown) + " -o " + q(out_mesh),
         mesh_unknown, 65, {out_mesh}},
        {"denoise: faces of no area", "denoise " + q(mesh_point) + " -o " + q(out_mesh),
         mesh_point, 65, {out_mesh}},
        {"denoise envt: faces of no area",
         "denoise " + q(mesh_point) + " --method envt -o " + q(out_mesh), mesh_point, 65,
         {out_mesh}},
        {"features: NaN vertex", "features " + q(mesh_nan) + " -o " + q(out_mesh), mesh_nan, 65,
         {out_mesh}},
        {"features: faces of no area", "features " + q(mesh_point) + " -o " + q(out_mesh),
         mesh_point, 65, {out_mesh}},
        {"metrics: missing reference", "metrics " + q(tri) + " --reference " + q(mesh_missing),
         mesh_missing, 66, {}},
        {"metrics: NaN reference", "metrics " + q(tri) + " --reference " + q(mesh_nan), mesh_nan,
         65, {}},
        {"metrics: input of another triangulation",
         "metrics " + q(tri) + " --reference " + q(tri) + " --input " + q(mesh_other), mesh_other,
         64, {}},
        {"metrics: --input, reference of another triangulation",
         "metrics " + q(tri) + " --reference " + q(mesh_other) + " --input " + q(tri), mesh_other,
         64, {}},
        {"features: output without face scalars", "features " + q(tri) + " -o " + q(out_json),
         out_json, 64, {out_json}},
        {"meanshape: NaN surface", "meanshape " + q(tri) + " " + q(mesh_nan) + " -o " +
         q(out_mesh), mesh_nan, 65, {out_mesh}},
        // Tables and folders.
        {"stats: missing table", "stats " + q(csv_missing), csv_missing, 66, {}},
        {"stats: empty table", "stats " + q(csv_empty), csv_empty, 65, {}},
        {"stats: not an eyes table", "stats " + q(csv_foreign), csv_foreign, 65, {}},
        {"merge: not a result", "merge " + q(json_bad) + " -o " + q(out_csv), json_bad, 65,
         {out_csv}},
        {"merge: missing result", "merge " + q(missing) + " -o " + q(out_csv), missing, 66,
         {out_csv}},
        {"merge: missing groups file", "merge " + q(json_bad) + " --groups " + q(csv_missing) +
         " -o " + q(out_csv), csv_missing, 66, {out_csv}},
        {"gallery: nothing to show", "gallery " + q(empty_outdir), empty_outdir, 66, {}},
        {"pseudonym: missing key file", "pseudonym --subject-key-file " + q(key_missing) + " P1",
         key_missing, 66, {}},
        {"cohort: missing input folder", "cohort " + q(tmp / "no_such_export_folder") + " -o " +
         q(tmp / "cohort_out"), tmp / "no_such_export_folder", 66, {}},
    };

    int passed = 0;
    for (const Case& c : cases) {
        for (const auto& o : c.outputs) fs::remove(o);
        const RunResult r = run_octshape_limited(c.args, 120);
        const std::string line = error_line(r.err);
        const std::string where = c.name + " (octshape " + c.args + "): exit " +
                                  std::to_string(r.exit_code) + ", stderr: " + r.err;
        const bool code_ok = r.exit_code == c.exit_code;
        EXPECT_TRUE(code_ok) << where;
        // One error line, and it is the last thing written (warnings may come before it).
        const bool one_line = !line.empty() && r.err.find("octshape: error: ", r.err.find(line) +
                                                          1) == std::string::npos &&
                              r.err.size() == r.err.find(line) + line.size() + 1;
        EXPECT_TRUE(one_line) << where;
        // The culprit as the user wrote it, followed by ": " and a cause of a few words.
        const std::string named = c.culprit.string() + ": ";
        const auto at = line.find(named);
        const bool names_file = at != std::string::npos;
        EXPECT_TRUE(names_file) << where;
        const bool has_cause = names_file && line.size() - (at + named.size()) >= 8;
        EXPECT_TRUE(has_cause) << where;
        const bool no_foreign_doc = line.find(spec_word()) == std::string::npos;
        EXPECT_TRUE(no_foreign_doc) << where;
        bool no_output = true;
        for (const auto& o : c.outputs) {
            if (fs::exists(o)) no_output = false;
            EXPECT_FALSE(fs::exists(o)) << where << " left " << o;
        }
        // The messages as a user reads them (temp folder shortened), for the record.
        const std::string tp = tmp.path().string();
        std::string shown;
        for (std::size_t from = 0;;) {
            const auto p = line.find(tp, from);
            shown.append(line, from, p == std::string::npos ? std::string::npos : p - from);
            if (p == std::string::npos) break;
            shown += "TMP";
            from = p + tp.size();
        }
        std::cout << (code_ok && one_line && has_cause && no_foreign_doc && no_output ? "ok   "
                                                                                      : "FAIL ")
                  << r.exit_code << "  " << c.name << "\n       " << shown << '\n';
        if (code_ok && one_line && has_cause && no_foreign_doc && no_output) ++passed;
    }
    std::cout << "message test: " << passed << " of " << cases.size() << " error paths\n";
}

// Every document a message, a help text or an output of octshape points its user to is in the
// repository (docs/...). Read off the string literals of the product's sources. That none points
// to the developers' internal spec, in a string or a comment, is Sources.CiteNoInternalSpec.
TEST(Messages, PointOnlyToDocumentsTheUserHas) {
    int references = 0;
    std::vector<std::string> bad;
    for (const char* dir : {"app", "base", "io", "libmesh", "libretina"}) {
        for (const auto& entry : fs::recursive_directory_iterator(source_dir() / dir)) {
            const auto ext = entry.path().extension();
            if (!entry.is_regular_file() || (ext != ".cpp" && ext != ".h")) continue;
            const std::string text = slurp(entry.path());
            std::size_t line_no = 1;
            // Code and string literals are read, comments skipped (the developers' notes may
            // cite what they like). String state is kept only to tell "//" inside a literal
            // (a URL) from a comment; a raw string spanning lines is read as code, which is
            // read all the same.
            bool in_string = false;
            for (std::size_t i = 0; i < text.size(); ++i) {
                const char c = text[i];
                if (c == '\n') {
                    ++line_no;
                    in_string = false;
                    continue;
                }
                if (in_string && c == '\\') {
                    ++i;
                    continue;
                }
                if (c == '"' && (i == 0 || text[i - 1] != '\'')) in_string = !in_string;
                if (!in_string && c == '/' && i + 1 < text.size() && text[i + 1] == '/') {
                    const auto eol = text.find('\n', i);
                    if (eol == std::string::npos) break;
                    i = eol - 1;  // the comment, to the end of the line
                    continue;
                }
                const auto where = [&] {
                    return fs::relative(entry.path(), source_dir()).string() + ":" +
                           std::to_string(line_no);
                };
                if (text.compare(i, 5, "docs/") == 0) {
                    std::size_t e = i + 5;
                    while (e < text.size() && (std::isalnum(static_cast<unsigned char>(text[e])) ||
                                               text[e] == '/' || text[e] == '_' ||
                                               text[e] == '-' || text[e] == '.')) {
                        ++e;
                    }
                    std::string doc = text.substr(i, e - i);
                    while (!doc.empty() && (doc.back() == '.' || doc.back() == '/')) doc.pop_back();
                    ++references;
                    if (!fs::exists(source_dir() / doc)) bad.push_back(where() + ": " + doc);
                }
            }
        }
    }
    for (const std::string& b : bad) ADD_FAILURE() << b;
    std::cout << references << " references to docs/ in the product's strings, " << bad.size()
              << " to a document the user does not have\n";
    EXPECT_GT(references, 10);  // the scan found the references (the grep above finds 17)
}

// The repository's own text files, as a reader of the sources meets them: sources, headers,
// scripts, build files and docs; not the build trees, git's files or the binary sample scans.
std::vector<fs::path> repository_text_files() {
    static const std::vector<std::string> kExt{".cpp", ".h",  ".hpp",  ".cc",   ".c",
                                               ".py",  ".sh", ".R",    ".txt",  ".cmake",
                                               ".in",  ".md", ".yaml", ".json", ".cff"};
    std::vector<fs::path> files;
    for (auto it = fs::recursive_directory_iterator(source_dir());
         it != fs::recursive_directory_iterator(); ++it) {
        const std::string name = it->path().filename().string();
        if (it->is_directory()) {
            if (name.starts_with(".") || name.starts_with("build") || name == "sample_scans") {
                it.disable_recursion_pending();
            }
            continue;
        }
        if (!it->is_regular_file()) continue;
        const std::string ext = it->path().extension().string();
        const bool no_ext = ext.empty() && !name.starts_with(".");  // Snakefile, ci/run
        if (no_ext || std::find(kExt.begin(), kExt.end(), ext) != kExt.end()) {
            files.push_back(it->path());
        }
    }
    return files;
}

// The product stands alone: no source, header, script, build file or doc cites the developers'
// internal spec (its name followed by anything but a letter: a section sign, a space, ".md"),
// in code, strings or comments, so that a new citation fails here. SPECTRALIS is a device.
TEST(Sources, CiteNoInternalSpec) {
    const std::string word = spec_word();
    const std::vector<fs::path> files = repository_text_files();
    std::vector<std::string> bad;
    for (const fs::path& f : files) {
        const std::string text = slurp(f);
        for (auto at = text.find(word); at != std::string::npos; at = text.find(word, at + 1)) {
            const std::size_t e = at + word.size();
            if (e < text.size() &&
                (std::isalpha(static_cast<unsigned char>(text[e])) != 0 || text[e] == '_')) {
                continue;  // a longer word (SPECTRALIS)
            }
            const auto line =
                1 + std::count(text.begin(), text.begin() + static_cast<long>(at), '\n');
            bad.push_back(fs::relative(f, source_dir()).string() + ":" + std::to_string(line));
        }
    }
    for (const std::string& b : bad) ADD_FAILURE() << b << ": cites the internal spec";
    std::cout << files.size() << " files read, " << bad.size() << " cite the internal spec\n";
    EXPECT_GT(files.size(), 250U);  // the walk found the repository (about 300 text files)
}

// No C or C++ source includes <regex> or uses std::regex: GCC 12 warns (-Wmaybe-uninitialized)
// inside <regex> at -O1, which fails the sanitizer build under -Werror (docs/development.md).
// Read per line: an #include of it, or one of its names in code (comments may say "not
// std::regex"). The needles are spelled in pieces so that this file does not match itself.
TEST(Sources, UseNoRegex) {
    const std::string header = std::string("<re") + "gex>";
    const std::vector<std::string> names{
        std::string("std::re") + "gex", "std::sm" + std::string("atch"),
        "std::cm" + std::string("atch"), "std::sre" + std::string("gex")};
    int sources = 0;
    std::vector<std::string> bad;
    for (const fs::path& f : repository_text_files()) {
        const std::string ext = f.extension().string();
        if (ext != ".cpp" && ext != ".h" && ext != ".hpp" && ext != ".cc" && ext != ".c") continue;
        ++sources;
        std::istringstream in(slurp(f));
        std::string line;
        for (int n = 1; std::getline(in, line); ++n) {
            const std::string code = line.substr(0, line.find("//"));
            const auto first = code.find_first_not_of(" \t");
            bool uses = first != std::string::npos && code[first] == '#' &&
                        code.find("include") != std::string::npos &&
                        code.find(header) != std::string::npos;
            for (const std::string& name : names)
                uses = uses || code.find(name) != std::string::npos;
            if (uses)
                bad.push_back(fs::relative(f, source_dir()).string() + ":" + std::to_string(n));
        }
    }
    for (const std::string& b : bad) ADD_FAILURE() << b << ": uses <regex>";
    std::cout << sources << " C/C++ sources read, " << bad.size() << " use <regex>\n";
    EXPECT_GT(sources, 250);  // the walk found the sources (about 280)
}

}  // namespace
}  // namespace octshape::test
