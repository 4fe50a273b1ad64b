// Streamed readers (lines/line_reader.hpp): every batch split gives the line set the whole read
// gives. Filled in by the streaming readers' work.
