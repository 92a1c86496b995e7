// Writes the seed corpus for topcon_fuzz into DIR: small .fda files written by write_topcon of a
// few sizes and eyes, with missing values (nothing is copied from ../shared). write_topcon
// writes the @IMG_JPEG chunk's header but no frames (a phantom .fda holds no pixels), so half
// of the seeds get one real JPEG 2000 frame per B-scan, coded here with OpenJPEG (lossless J2K
// codestreams of a small B-scan: dark vitreous, a bright band between the ILM and BM lines, a
// dim choroid), so that the fuzzer starts inside OpenJPEG's decoder and not only at its
// header check. Every seed with frames is read back with pixels before it is written: a seed
// whose frames the reader does not decode is an error here (exit 70), not a silent weak corpus.
// Usage: make_topcon_seeds DIR

#include <openjpeg.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "octshape/io/topcon.h"

namespace {

// OpenJPEG's output stream into a string (write at a cursor; skip and seek move it).
struct Buffer {
    std::string bytes;
    std::size_t pos = 0;
};

OPJ_SIZE_T write_fn(void* data, OPJ_SIZE_T n, void* user) {
    auto* b = static_cast<Buffer*>(user);
    if (b->bytes.size() < b->pos + n) b->bytes.resize(b->pos + n);
    std::memcpy(b->bytes.data() + b->pos, data, n);
    b->pos += n;
    return n;
}

OPJ_OFF_T skip_fn(OPJ_OFF_T n, void* user) {
    auto* b = static_cast<Buffer*>(user);
    if (n < 0 && static_cast<std::size_t>(-n) > b->pos) return -1;
    b->pos = static_cast<std::size_t>(static_cast<OPJ_OFF_T>(b->pos) + n);
    if (b->bytes.size() < b->pos) b->bytes.resize(b->pos);
    return n;
}

OPJ_BOOL seek_fn(OPJ_OFF_T to, void* user) {
    auto* b = static_cast<Buffer*>(user);
    if (to < 0) return OPJ_FALSE;
    b->pos = static_cast<std::size_t>(to);
    if (b->bytes.size() < b->pos) b->bytes.resize(b->pos);
    return OPJ_TRUE;
}

// A lossless 8-bit J2K codestream of B-scan `b` of `s` (row 0 at the top, as the device stores
// it). Exits 70 if OpenJPEG fails.
std::string code_frame(const octshape::io::Scan& s, std::size_t b) {
    const auto w = static_cast<OPJ_UINT32>(s.meta.size_x);
    const auto h = static_cast<OPJ_UINT32>(s.meta.size_z);
    opj_image_cmptparm_t cm{};
    cm.dx = 1;
    cm.dy = 1;
    cm.w = w;
    cm.h = h;
    cm.prec = 8;
    cm.sgnd = 0;
    opj_image_t* image = opj_image_create(1, &cm, OPJ_CLRSPC_GRAY);
    opj_codec_t* codec = opj_create_compress(OPJ_CODEC_J2K);
    opj_stream_t* stream = opj_stream_default_create(OPJ_FALSE);
    Buffer out;
    bool ok = image != nullptr && codec != nullptr && stream != nullptr;
    if (ok) {
        image->x0 = 0;
        image->y0 = 0;
        image->x1 = w;
        image->y1 = h;
        const auto& seg = s.bscans[b].seg;
        for (OPJ_UINT32 a = 0; a < w; ++a) {
            const float ilm = seg[0][a];
            const float bm = seg[1][a];
            for (OPJ_UINT32 z = 0; z < h; ++z) {
                const auto zf = static_cast<float>(z);
                int v = 20;  // vitreous, and every A-scan without lines
                if (!std::isnan(ilm) && !std::isnan(bm)) {
                    v = zf < ilm ? 20 : zf <= bm ? 180 + static_cast<int>((a * 7 + z * 3) % 50) : 90;
                }
                image->comps[0].data[z * w + a] = v;
            }
        }
        opj_cparameters_t p;
        opj_set_default_encoder_parameters(&p);
        p.tcp_numlayers = 1;
        p.tcp_rates[0] = 0.0F;  // lossless
        p.cp_disto_alloc = 1;
        // Resolution levels: each halves the image; the smallest side must keep >= 1 px.
        p.numresolution = std::max(1, std::min(3, static_cast<int>(std::log2(std::min(w, h))) + 1));
        opj_stream_set_write_function(stream, write_fn);
        opj_stream_set_skip_function(stream, skip_fn);
        opj_stream_set_seek_function(stream, seek_fn);
        opj_stream_set_user_data(stream, &out, nullptr);
        ok = opj_setup_encoder(codec, &p, image) && opj_start_compress(codec, image, stream) &&
             opj_encode(codec, stream) && opj_end_compress(codec, stream);
    }
    if (stream != nullptr) opj_stream_destroy(stream);
    if (codec != nullptr) opj_destroy_codec(codec);
    if (image != nullptr) opj_image_destroy(image);
    if (!ok) {
        std::cerr << "make_topcon_seeds: OpenJPEG could not code a frame\n";
        std::exit(70);
    }
    return out.bytes;
}

// The file of write_topcon with one coded frame per B-scan in its @IMG_JPEG chunk (25 bytes of
// header, the frame count at byte 17, then each frame as u32 size + codestream).
std::string with_frames(const std::string& file, const octshape::io::Scan& s) {
    const std::size_t at = file.find("@IMG_JPEG");
    const std::size_t data = at + 9 + 4;
    std::string chunk = file.substr(data, 25);
    const auto frames = static_cast<std::uint32_t>(s.bscans.size());
    std::memcpy(chunk.data() + 17, &frames, 4);
    for (std::size_t b = 0; b < s.bscans.size(); ++b) {
        const std::string f = code_frame(s, b);
        const auto n = static_cast<std::uint32_t>(f.size());
        chunk.append(reinterpret_cast<const char*>(&n), 4);
        chunk += f;
    }
    const auto size = static_cast<std::uint32_t>(chunk.size());
    return file.substr(0, at + 9) + std::string(reinterpret_cast<const char*>(&size), 4) + chunk +
           file.substr(data + 25);
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::cerr << "usage: make_topcon_seeds DIR\n";
        return 64;
    }
    const std::filesystem::path dir(argv[1]);
    std::filesystem::create_directories(dir);
    int n = 0;
    for (const int x : {3, 8}) {
        for (const int bscans : {2, 5}) {
            for (const auto eye : {octshape::io::Laterality::kOD, octshape::io::Laterality::kOS}) {
                octshape::io::Scan s;
                s.meta.size_x = x;
                s.meta.size_z = 40;
                s.meta.scale_x_mm = 6.0 / x;
                s.meta.scale_z_mm = 0.0035;
                s.meta.distance_mm = 6.0 / (bscans - 1);
                s.meta.laterality = eye;
                s.bscans.resize(static_cast<std::size_t>(bscans));
                for (int b = 0; b < bscans; ++b) {
                    auto& seg = s.bscans[static_cast<std::size_t>(b)].seg;
                    seg.assign(2, std::vector<float>(static_cast<std::size_t>(x)));
                    for (int a = 0; a < x; ++a) {
                        seg[0][static_cast<std::size_t>(a)] = static_cast<float>(5 + (a + b) % 3);
                        seg[1][static_cast<std::size_t>(a)] = static_cast<float>(30 + a % 2);
                    }
                }
                s.bscans[0].seg[0][0] = std::numeric_limits<float>::quiet_NaN();
                std::ostringstream raw(std::ios::binary);
                octshape::io::write_topcon(s, raw, 4);
                std::ofstream(dir / ("seed" + std::to_string(n++) + ".fda"), std::ios::binary)
                    << raw.str();
                // The same file with its B-scans as JPEG 2000 frames, checked to decode.
                const std::string coded = with_frames(raw.str(), s);
                octshape::io::ReadOptions px;
                px.pixels = true;
                const octshape::io::Scan back = octshape::io::parse_topcon(coded, "seed.fda", px);
                if (!back.pixels_loaded) {
                    std::cerr << "make_topcon_seeds: a coded seed reads without pixels\n";
                    return 70;
                }
                std::ofstream(dir / ("seed" + std::to_string(n++) + "_j2k.fda"), std::ios::binary)
                    << coded;
            }
        }
    }
    return 0;
}
