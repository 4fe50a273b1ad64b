#pragma once
// A status line drawn into an image: a 5x7 pixel font (upper case, digits and the punctuation a
// status line needs; lower case is drawn as upper case), white on a dark band. For the viewer's
// on-screen line, which must work without any font library or GPU text rendering.

#include <string>

#include "render/image.hpp"

namespace linebake {

// Draws `text` on a dark band across the image from row `y`, glyphs `scale` pixels per font
// pixel. Characters outside the font draw as a small box. Clipped to the image.
void draw_status_line(Image& image, const std::string& text, int y = 0, int scale = 2);

}  // namespace linebake
