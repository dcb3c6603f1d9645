// The human output of rcanctl: rows of cells in left-aligned columns, two spaces apart.
#pragma once

#include <ostream>
#include <string>
#include <vector>

namespace rcand::rcanctl {

// cells[0] is the header row; every row has the same number of cells.
void print_text_table(const std::vector<std::vector<std::string>>& cells, std::ostream& out);

}  // namespace rcand::rcanctl
