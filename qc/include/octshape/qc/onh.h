#pragma once
// QC pictures of one ONH analysis (`octshape onh --qc DIR`): the en-face height map with the
// BMO points, the ellipse and the disc circle; B-scans through the disc with the ILM used over
// the device lines and the MRW vectors; the MRW per BMO point against the anatomical angle.

#include <string>

#include "octshape/io/scan.h"
#include "octshape/retina/onh.h"

namespace octshape::qc {

// Writes DIR/STEM_enface.png, DIR/STEM_bscans.png and DIR/STEM_mrw.png (atomically). The
// B-scans show the pixels when the scan was read with them, else a black background.
// Throws OutputError.
void write_onh_qc(const io::Scan& scan,
                  const retina::OnhResult& r,
                  const retina::OnhParams& p,
                  const std::string& dir,
                  const std::string& stem);

}  // namespace octshape::qc
