// libjpeg's error handling for the encoder and the decoder: a fatal error longjmps back into the call that made it
// (a C++ exception must not unwind through libjpeg's C frames, and its default handler calls exit()), and warnings
// (a corrupt but usable picture) are dropped instead of printed to stderr. Include after jpeglib.h.
#pragma once

#include <csetjmp>

namespace rcand::plugins::vision {

struct JpegErrors {
  jpeg_error_mgr pub;  // first: libjpeg hands back &pub, cast back to the whole
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];

  // Makes this the error manager of `cinfo`; a caller then does `if (setjmp(jump) != 0) ...` before each libjpeg call.
  jpeg_error_mgr* install() {
    jpeg_error_mgr* manager = jpeg_std_error(&pub);
    pub.error_exit = fail;
    pub.output_message = quiet;
    return manager;
  }

 private:
  static void fail(j_common_ptr cinfo) {
    auto* errors = reinterpret_cast<JpegErrors*>(cinfo->err);
    (*cinfo->err->format_message)(cinfo, errors->message);
    std::longjmp(errors->jump, 1);
  }
  static void quiet(j_common_ptr) {}
};

}  // namespace rcand::plugins::vision
