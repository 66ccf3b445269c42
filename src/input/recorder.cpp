#include "arthrosim/input/recorder.h"

#include <vector>

#include "arthrosim/core/error.h"
#include "arthrosim/input/session.h"

namespace arthrosim::input {

SessionCsvWriter::SessionCsvWriter(const std::string& path, const Model& model)
    : model_(model), path_(path), file_(std::fopen(path.c_str(), "wb")) {
  if (file_ == nullptr) throw InputError(path, 0, "", "cannot create session record file");
  std::fprintf(file_, "%s\n", SessionCsvHeader());
  std::fflush(file_);
}

SessionCsvWriter::~SessionCsvWriter() {
  if (file_ != nullptr) std::fclose(file_);
}

void SessionCsvWriter::Write(double t_s, const InputFrame& frame) {
  std::vector<SessionRow> rows;
  AppendFrameRows(model_, t_s, frame, &rows);
  for (const SessionRow& r : rows) {
    const std::string line = FormatSessionCsvRow(r);
    std::fwrite(line.data(), 1, line.size(), file_);
    std::fputc('\n', file_);
  }
  if (std::fflush(file_) != 0) throw InputError(path_, 0, "", "write failed");
}

}  // namespace arthrosim::input
