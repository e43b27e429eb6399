// `ambdiag convert IN OUT`: UFF58/58b <-> FRF file, chosen by extension.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <sstream>

#include "ambdiag/core/error.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/io_util.h"
#include "ambdiag/core/uff58.h"
#include "args.h"
#include "command.h"

namespace ambdiag::cli {

namespace {

enum class Kind { uff, csv };

Kind kind_of(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".uff" || ext == ".unv") return Kind::uff;
  if (ext == ".csv") return Kind::csv;
  throw UsageError("cannot tell the format of \"" + path + "\" (use .uff, .unv or .csv)");
}

// Non-FRF datasets (time data, spectra): a CSV of the abscissa and one
// column (or re/im pair) per record; the records must share the abscissa.
std::string records_csv(const std::vector<Uff58Record>& recs, const std::string& source) {
  const auto& x = recs.front().x;
  std::ostringstream out;
  out << std::setprecision(17);
  out << "# converted from " << std::filesystem::path(source).filename().string() << "\n";
  out << "x_" << (recs.front().abscissa.units.empty() ? "unit" : recs.front().abscissa.units);
  for (size_t r = 0; r < recs.size(); ++r) {
    if (recs[r].x != x) {
      throw InputError(source + ": dataset " + std::to_string(r + 1) +
                       " has another abscissa than dataset 1; convert one with --record N");
    }
    const std::string name = "y" + std::to_string(r + 1);
    out << "," << name << (recs[r].is_complex() ? "_re," + name + "_im" : "");
  }
  out << "\n";
  for (size_t i = 0; i < x.size(); ++i) {
    out << x[i];
    for (const auto& r : recs) {
      out << "," << r.y[i].real();
      if (r.is_complex()) out << "," << r.y[i].imag();
    }
    out << "\n";
  }
  return out.str();
}

int run_convert(const std::vector<std::string>& argv) {
  const Args args(argv, {"--record"}, {"--binary"});
  args.expect_positional(2, "IN and OUT");
  const std::string in = args.positional()[0], out = args.positional()[1];
  const Kind from = kind_of(in), to = kind_of(out);
  if (from == Kind::uff && to == Kind::csv) {
    std::vector<Uff58Record> recs = read_uff58(in);
    if (recs.empty()) throw InputError(in + ": no dataset 58 or 58b in the file");
    if (auto r = args.number("--record")) {
      if (*r < 1 || *r > static_cast<double>(recs.size()))
        throw UsageError("--record: must be in 1.." + std::to_string(recs.size()));
      recs = {recs[static_cast<size_t>(*r) - 1]};
    }
    const bool all_frf = std::all_of(recs.begin(), recs.end(), [](const Uff58Record& r) { return r.func_type == 4; });
    if (all_frf) {
      write_frf_csv(out, frf_from_uff58(recs));
    } else {
      write_file_atomic(out, records_csv(recs, in));
    }
    std::fprintf(stderr, "converted %zu dataset(s) of %s to %s (%s)\n", recs.size(), in.c_str(), out.c_str(),
                 all_frf ? "FRF file" : "abscissa/ordinate CSV");
    return kExitOk;
  }
  if (from == Kind::csv && to == Kind::uff) {
    const FrfData frf = read_frf_csv(in);
    const auto recs = frf_to_uff58(frf);
    write_uff58(out, recs, args.flag("--binary"));
    std::fprintf(stderr, "converted %zu FRF(s) of %s to %s (%s)\n", recs.size(), in.c_str(), out.c_str(),
                 args.flag("--binary") ? "58b binary" : "58 ASCII");
    return kExitOk;
  }
  throw UsageError("convert goes between UFF58 (.uff, .unv) and CSV (.csv)");
}

}  // namespace

std::vector<Command> convert_commands() {
  return {{{"convert"},
           "convert between UFF58/58b and the FRF file",
           "usage: ambdiag convert IN OUT [--binary] [--record N]\n\n"
           "Formats by extension:\n"
           "  .uff/.unv -> .csv  datasets 58/58b; FRFs (function type 4) become an ambdiag.frf/1 file,\n"
           "                     other functions (time data, spectra) a CSV of abscissa and ordinates\n"
           "  .csv -> .uff/.unv  an ambdiag.frf/1 file as one dataset 58 per FRF entry\n\n"
           "  --binary    write binary 58b instead of ASCII 58\n"
           "  --record N  convert only the N-th dataset of the universal file\n",
           run_convert}};
}

}  // namespace ambdiag::cli
