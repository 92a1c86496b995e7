// Safe to hand over (docs/cohort.md "Output folder", docs/outputs.md "Privacy", "Provenance",
// "Output paths"): a planted patient name reaches no byte outside OUTDIR/private/; results
// carry the code that made them, and a resumed cohort redoes exactly the eyes another code made;
// outputs go to stdout, devices, FIFOs and through symbolic links as Unix users expect, and a
// run that cannot write leaves nothing behind.

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "octshape/io/vol.h"
#include "octshape/retina/phantom_macula.h"
#include "fixtures/small_macula.h"
#include "test_paths.h"

namespace octshape {
namespace {

using nlohmann::json;
using test::read_csv;
using test::slurp;
using test::spit;
namespace fs = std::filesystem;

std::string q(const fs::path& p) {
    std::string s("'");
    s.append(p.string()).append("'");
    return s;
}

// The planted name: Heidelberg names exports SURNAME_FIRST_PATIENTNO_N.vol, and study folders
// are often named after the patient too; the header's identifier fields carry it as well.
constexpr const char* kSurname = "Mustermann";
constexpr const char* kFolder = "Mustermann_Max";

// A small macula volume (25 x 192, no pixels) whose header identifiers all hold the name.
void write_named_macula(const fs::path& path, io::Laterality eye, std::uint64_t seed) {
    io::Scan s = test::small_macula_scan(retina::MaculaFamily::kBezier, eye, seed);
    s.meta.ids.id = "Mustermann_Max";
    s.meta.ids.reference_id = "Mustermann";
    s.meta.ids.patient_id = "Mustermann_Max_4711";
    s.meta.ids.visit_id = "Mustermann";
    io::write_vol_file(s, path.string());
}

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return s;
}

struct Scan {
    std::size_t files = 0;
    std::uintmax_t bytes = 0;
    std::vector<std::string> hits;  // files holding the name (any case)
};

// Every byte of every regular file under `root` (skipping `skip` when not empty), searched
// for the surname in any case, and for the file's own name.
Scan search(const fs::path& root, const fs::path& skip = {}) {
    Scan s;
    const std::string needle = lower(kSurname);
    for (auto it = fs::recursive_directory_iterator(root); it != fs::recursive_directory_iterator();
         ++it) {
        if (!skip.empty() && it->path() == skip) {
            it.disable_recursion_pending();
            continue;
        }
        if (lower(it->path().filename().string()).find(needle) != std::string::npos) {
            s.hits.push_back(it->path().string() + " (its name)");
        }
        if (!it->is_regular_file()) continue;
        const std::string bytes = slurp(it->path());
        ++s.files;
        s.bytes += bytes.size();
        if (lower(bytes).find(needle) != std::string::npos) s.hits.push_back(it->path().string());
    }
    return s;
}

std::string joined(const std::vector<std::string>& v) {
    std::string s;
    for (const auto& x : v) s += x + "\n";
    return s;
}

TEST(Privacy, APlantedNameReachesNothingOutsidePrivate) {
    test::TempDir dir;
    const fs::path in = dir / "in" / kFolder;
    fs::create_directories(in);
    write_named_macula(in / "Mustermann_Max_4711_0.vol", io::Laterality::kOD, 1);
    write_named_macula(in / "Mustermann_Max_4711_1.vol", io::Laterality::kOS, 2);
    // A failure whose reason names the file, and an ONH eye (its own JSON, pictures, table).
    const std::string good = slurp(in / "Mustermann_Max_4711_0.vol");
    spit(in / "Mustermann_Max_4711_2.vol", good.substr(0, good.size() / 2));
    const auto onh = test::run_octshape("phantom onh --bscans 25 --ascans 96 -o " +
                                        q(in / "Mustermann_Max_4711_3.vol"));
    ASSERT_EQ(onh.exit_code, 0) << onh.err;
    fs::remove(in / "Mustermann_Max_4711_3.truth.json");

    // No subject option (the cohort's own key), QC pictures and the gallery.
    const fs::path out = dir / "out";
    const auto r = test::run_octshape("cohort " + q(dir / "in") + " -o " + q(out) +
                                      " --qc --jobs 2");
    ASSERT_EQ(r.exit_code, 1) << r.err;  // the truncated export failed
    const auto g = test::run_octshape("gallery " + q(out));
    ASSERT_EQ(g.exit_code, 0) << g.err;
    ASSERT_TRUE(fs::exists(out / "qc" / "index.html"));
    ASSERT_EQ(read_csv(out / "eyes.csv").size(), 3U);      // header + 2 maculae
    ASSERT_EQ(read_csv(out / "eyes_onh.csv").size(), 2U);  // header + the ONH eye
    ASSERT_EQ(read_csv(out / "failures.csv").size(), 2U);  // header + the truncated file
    // The log at its default level names eyes by their key, never by path (a log is kept and
    // shared); the failure's reason is scrubbed as in failures.csv.
    EXPECT_EQ(lower(r.err).find("mustermann"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("<input>"), std::string::npos) << r.err;
    EXPECT_EQ(lower(g.err).find("mustermann"), std::string::npos) << g.err;

    const Scan shared = search(out, out / "private");
    std::cerr << "[ planted name ] outside private/: " << shared.files << " files, "
              << shared.bytes << " bytes, " << shared.hits.size() << " hits\n";
    EXPECT_TRUE(shared.hits.empty()) << joined(shared.hits);
    EXPECT_GE(shared.files, 15U);  // 3 eye JSON, 1 failure JSON, 3 tables, 9 pictures, the page
    // The control: the name did reach the pipeline, and private/ is where it went.
    const Scan all = search(out);
    EXPECT_FALSE(all.hits.empty());
    for (const auto& h : all.hits) {
        EXPECT_EQ(h.rfind((out / "private").string() + "/", 0), 0U) << h;
    }
    EXPECT_NE(slurp(out / "private" / "inputs.csv").find("Mustermann_Max_4711_0.vol"),
              std::string::npos);
    EXPECT_NE(slurp(out / "private" / "failures.csv").find("Mustermann_Max_4711_2.vol"),
              std::string::npos);
}

TEST(Privacy, SingleEyeOutputsHoldNoNameUnlessAskedAndPicturesFollowTheOutput) {
    test::TempDir dir;
    fs::create_directories(dir / kFolder);
    const fs::path vol = dir / kFolder / "Mustermann_Max_4711_0.vol";
    write_named_macula(vol, io::Laterality::kOD, 3);
    const fs::path out = dir / "out";
    fs::create_directories(out);
    const auto r = test::run_octshape("macula " + q(vol) + " -o " + q(out / "left.json") +
                                      " --csv " + q(out / "left.csv") + " --qc " + q(out / "qc"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    // The log names the eye by its key; -v (debug) adds the path, for the person at the
    // terminal.
    EXPECT_EQ(lower(r.err).find("mustermann"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("eye "), std::string::npos) << r.err;
    const auto verbose = test::run_octshape("macula " + q(vol) + " -v -o " +
                                            q(dir / "verbose.json"));
    ASSERT_EQ(verbose.exit_code, 0) << verbose.err;
    EXPECT_NE(verbose.err.find(vol.string()), std::string::npos) << verbose.err;
    const auto info = test::run_octshape("info --json " + q(vol));
    ASSERT_EQ(info.exit_code, 0) << info.err;
    spit(out / "info.json", info.out);
    const Scan s = search(out);
    EXPECT_TRUE(s.hits.empty()) << joined(s.hits);
    EXPECT_EQ(s.files, 6U);  // JSON, CSV, three pictures, info
    EXPECT_TRUE(fs::exists(out / "qc" / "left_thickness.png"));
    EXPECT_TRUE(fs::exists(out / "qc" / "left_profiles.png"));
    EXPECT_TRUE(fs::exists(out / "qc" / "left_bscan.png"));
    const json j = json::parse(slurp(out / "left.json"));
    EXPECT_EQ(j["input"]["sha256"].get<std::string>().size(), 64U);  // what identifies it

    // --record-paths restores the paths (documented as identifying).
    const auto rp = test::run_octshape("macula " + q(vol) + " --record-paths");
    ASSERT_EQ(rp.exit_code, 0) << rp.err;
    EXPECT_EQ(json::parse(rp.out)["input"]["path"], vol.string());
    const auto ip = test::run_octshape("info --json --record-paths " + q(vol));
    EXPECT_NE(ip.out.find("Mustermann_Max_4711_0.vol"), std::string::npos);
}

// ---- Provenance ---------------------------------------------------------------------------

TEST(Provenance, VersionRevisionTimeStagesAndAFingerprintOfEveryParameter) {
    const auto v = test::run_octshape("--version");
    ASSERT_EQ(v.exit_code, 0);
    // "octshape X.Y.Z (revision <12 hex>|unknown[, modified]; <describe>; build <type>)".
    // (Checked by hand: GCC 12's <regex> trips -Wmaybe-uninitialized under the sanitizers.)
    const std::string head = "octshape ";
    ASSERT_EQ(v.out.rfind(head, 0), 0U) << v.out;
    const std::size_t rev = v.out.find(" (revision ");
    ASSERT_NE(rev, std::string::npos) << v.out;
    const std::string id = v.out.substr(rev + 11, v.out.find_first_of(",;", rev + 11) - rev - 11);
    const bool hex12 = id.size() == 12 && id.find_first_not_of("0123456789abcdef") == std::string::npos;
    EXPECT_TRUE(hex12 || id == "unknown") << v.out;
    EXPECT_NE(v.out.find("; build "), std::string::npos) << v.out;
    EXPECT_NE(v.out.find(")"), std::string::npos) << v.out;

    test::TempDir dir;
    write_named_macula(dir / "a.vol", io::Laterality::kOD, 4);
    const auto r1 = test::run_octshape("macula " + q(dir / "a.vol"));
    ASSERT_EQ(r1.exit_code, 0) << r1.err;
    const json j = json::parse(r1.out);
    const json& p = j["provenance"];
    for (const char* k : {"version", "revision", "modified", "build_type", "utc"}) {
        EXPECT_TRUE(p[k].is_string()) << k;
    }
    // YYYY-MM-DDTHH:MM:SSZ
    const std::string utc = p["utc"].get<std::string>();
    const std::string shape = "dddd-dd-ddTdd:dd:ddZ";
    bool utc_ok = utc.size() == shape.size();
    for (std::size_t i = 0; utc_ok && i < shape.size(); ++i) {
        utc_ok = shape[i] == 'd' ? std::isdigit(static_cast<unsigned char>(utc[i])) != 0
                                 : utc[i] == shape[i];
    }
    EXPECT_TRUE(utc_ok) << utc;
    for (const char* stage : {"read_hash", "analysis"}) {
        ASSERT_TRUE(p["seconds"][stage].is_number()) << stage;
        EXPECT_GE(p["seconds"][stage].get<double>(), 0.0);
    }
    // The fingerprint's text holds the code defaults the command line does not expose.
    const std::string text = j["cohort"]["options"];
    for (const char* k : {"local_fit_min_noise_um=", "energy_tolerance=", "max_rounds=",
                          "classifier_min_gap_mm="}) {
        EXPECT_NE(text.find(k), std::string::npos) << k;
    }
    // Same code, same parameters, same file: the same fingerprint, however the time differs;
    // another parameter: another fingerprint.
    std::this_thread::sleep_for(std::chrono::milliseconds(1100));
    const json j2 = json::parse(test::run_octshape("macula " + q(dir / "a.vol")).out);
    EXPECT_NE(j2["provenance"]["utc"], "");
    EXPECT_EQ(j2["cohort"]["fingerprint"], j["cohort"]["fingerprint"]);
    const json j3 = json::parse(test::run_octshape("macula " + q(dir / "a.vol") + " --tau-um 6").out);
    EXPECT_NE(j3["cohort"]["fingerprint"], j["cohort"]["fingerprint"]);
}

TEST(Provenance, ResumeRedoesExactlyTheEyesOfAnotherFingerprintAndMergeRefusesAMix) {
    test::TempDir dir;
    fs::create_directories(dir / "in");
    for (int i = 0; i < 4; ++i) {
        write_named_macula(dir / "in" / ("e" + std::to_string(i) + ".vol"),
                           i % 2 == 0 ? io::Laterality::kOD : io::Laterality::kOS,
                           static_cast<std::uint64_t>(10 + i));
    }
    const fs::path out = dir / "out";
    const std::string cmd = "cohort " + q(dir / "in") + " -o " + q(out) + " --jobs 2";
    ASSERT_EQ(test::run_octshape(cmd).exit_code, 0);
    const std::string csv = slurp(out / "eyes.csv");
    std::vector<fs::path> recs;
    for (const auto& e : fs::directory_iterator(out / "eyes")) recs.push_back(e.path());
    std::sort(recs.begin(), recs.end());
    ASSERT_EQ(recs.size(), 4U);
    // Two records as another revision of octshape would have left them (other fingerprint).
    std::map<fs::path, std::string> before;
    for (std::size_t i = 0; i < recs.size(); ++i) {
        if (i == 1 || i == 2) {
            json j = json::parse(slurp(recs[i]));
            j["cohort"]["fingerprint"] = "0000000000000000";
            spit(recs[i], j.dump(2) + "\n");
        }
        before[recs[i]] = slurp(recs[i]);
    }
    // merge refuses the mixed table (naming a file of the minority), or flags it on request.
    const auto m = test::run_octshape("merge " + q(out / "eyes"));
    EXPECT_EQ(m.exit_code, 65);
    EXPECT_NE(m.err.find("made by different code or parameters (2 fingerprints"),
              std::string::npos)
        << m.err;
    const auto ma = test::run_octshape("merge --allow-mixed " + q(out / "eyes"));
    ASSERT_EQ(ma.exit_code, 0) << ma.err;
    EXPECT_NE(ma.out.find(",fingerprint\n"), std::string::npos);
    EXPECT_NE(ma.out.find(",0000000000000000\n"), std::string::npos);

    const auto r = test::run_octshape(cmd);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("2 to do"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("2 eye(s) redone: their results were made by other code"),
              std::string::npos)
        << r.err;
    for (std::size_t i = 0; i < recs.size(); ++i) {
        const std::string now = slurp(recs[i]);
        if (i == 1 || i == 2) {
            EXPECT_NE(now, before[recs[i]]) << recs[i];  // redone
            EXPECT_NE(json::parse(now)["cohort"]["fingerprint"], "0000000000000000");
        } else {
            EXPECT_EQ(now, before[recs[i]]) << recs[i];  // untouched, byte for byte
        }
    }
    // Deterministic tables: the redone eyes give the same rows (the times are not in them).
    EXPECT_EQ(slurp(out / "eyes.csv"), csv);
    EXPECT_EQ(test::run_octshape("merge " + q(out / "eyes")).out, csv);
}

// ---- Output paths -------------------------------------------------------------------------

struct OneEye {
    test::TempDir dir;
    fs::path vol;
    OneEye() : vol(dir / "a.vol") { write_named_macula(vol, io::Laterality::kOD, 5); }
};

TEST(OutputPaths, DashIsStdout) {
    OneEye e;
    const auto j = test::run_octshape("macula " + q(e.vol) + " -o - --csv " + q(e.dir / "a.csv"));
    ASSERT_EQ(j.exit_code, 0) << j.err;
    EXPECT_EQ(json::parse(j.out)["command"], "macula");
    EXPECT_FALSE(fs::exists(fs::current_path() / "-"));
    const auto c = test::run_octshape("macula " + q(e.vol) + " --csv - -o " + q(e.dir / "a.json"));
    ASSERT_EQ(c.exit_code, 0) << c.err;
    EXPECT_EQ(c.out, slurp(e.dir / "a.csv"));  // the same row as written to a file
    EXPECT_EQ(test::run_octshape("macula " + q(e.vol) + " -o - --csv -").exit_code, 64);
}

TEST(OutputPaths, ADeviceNodeAndAFifoAreWrittenIntoNeverReplaced) {
    OneEye e;
    // A FIFO: a reader on the other end receives the whole JSON; the FIFO stays a FIFO.
    const fs::path fifo = e.dir / "out.fifo";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    std::string got;
    std::thread reader([&] { got = slurp(fifo); });  // opens (waits for the writer), reads to EOF
    const auto r = test::run_octshape("macula " + q(e.vol) + " -o " + q(fifo));
    reader.join();
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(json::parse(got)["command"], "macula");
    EXPECT_TRUE(fs::is_fifo(fifo));

    // A character device made here (1:3, a null device; never the system's /dev/null).
    const fs::path dev = e.dir / "null";
    if (::mknod(dev.c_str(), S_IFCHR | 0666, makedev(1, 3)) != 0) {
        GTEST_SKIP() << "mknod needs privileges here: " << std::strerror(errno);
    }
    const auto d = test::run_octshape("macula " + q(e.vol) + " -o " + q(dev) + " --csv " +
                                      q(dev));
    ASSERT_EQ(d.exit_code, 0) << d.err;
    EXPECT_TRUE(fs::is_character_file(dev));
    struct stat st {};
    ASSERT_EQ(::stat(dev.c_str(), &st), 0);
    EXPECT_EQ(st.st_rdev, makedev(1, 3));
    // Nothing else appeared in the folder (no temporary left, no file in its place).
    std::vector<std::string> names;
    for (const auto& x : fs::directory_iterator(e.dir.path())) {
        names.push_back(x.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, (std::vector<std::string>{"a.vol", "null", "out.fifo"}));
}

TEST(OutputPaths, ASymlinkIsWrittenThroughAndKept) {
    OneEye e;
    fs::create_directories(e.dir / "real");
    spit(e.dir / "real" / "eye.json", "old");
    fs::create_symlink("real/eye.json", e.dir / "link.json");  // relative, as users make them
    const auto r = test::run_octshape("macula " + q(e.vol) + " -o " + q(e.dir / "link.json"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(fs::is_symlink(e.dir / "link.json"));
    EXPECT_EQ(fs::read_symlink(e.dir / "link.json"), "real/eye.json");
    EXPECT_EQ(json::parse(slurp(e.dir / "real" / "eye.json"))["command"], "macula");
    // A dangling link: its target is created.
    fs::create_symlink("real/new.json", e.dir / "dangling.json");
    ASSERT_EQ(test::run_octshape("macula " + q(e.vol) + " -o " + q(e.dir / "dangling.json"))
                  .exit_code,
              0);
    EXPECT_TRUE(fs::is_symlink(e.dir / "dangling.json"));
    EXPECT_EQ(json::parse(slurp(e.dir / "real" / "new.json"))["command"], "macula");
}

TEST(OutputPaths, AnUnwritableOutputIsFoundFirstAndLeavesNothingBehind) {
    OneEye e;
    // -o in a missing folder, with --csv and --qc that could be written: refused before the
    // analysis (exit 73), and neither the CSV nor a picture appears.
    const auto r = test::run_octshape("macula " + q(e.vol) + " -o " +
                                      q(e.dir / "missing" / "eye.json") + " --csv " +
                                      q(e.dir / "eye.csv") + " --qc " + q(e.dir / "qc"));
    EXPECT_EQ(r.exit_code, 73) << r.err;
    EXPECT_NE(r.err.find("missing/eye.json: cannot write: directory does not exist"),
              std::string::npos)
        << r.err;
    EXPECT_FALSE(fs::exists(e.dir / "eye.csv"));
    EXPECT_FALSE(fs::exists(e.dir / "qc"));
    // -o onto a directory: the same.
    fs::create_directories(e.dir / "adir");
    const auto d = test::run_octshape("macula " + q(e.vol) + " -o " + q(e.dir / "adir") +
                                      " --csv " + q(e.dir / "eye.csv"));
    EXPECT_EQ(d.exit_code, 73) << d.err;
    EXPECT_FALSE(fs::exists(e.dir / "eye.csv"));
    // A failed analysis (an ONH volume refused by macula) writes nothing either.
    const auto onh = test::run_octshape("phantom onh --bscans 25 --ascans 96 -o " +
                                        q(e.dir / "onh.vol"));
    ASSERT_EQ(onh.exit_code, 0) << onh.err;
    const auto f = test::run_octshape("macula " + q(e.dir / "onh.vol") + " -o " +
                                      q(e.dir / "eye.json") + " --csv " + q(e.dir / "eye.csv") +
                                      " --qc " + q(e.dir / "qc"));
    EXPECT_EQ(f.exit_code, 69) << f.err;
    for (const char* n : {"eye.json", "eye.csv", "qc"}) EXPECT_FALSE(fs::exists(e.dir / n)) << n;
}

}  // namespace
}  // namespace octshape
