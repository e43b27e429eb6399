// Universal File Format dataset 58 (function at nodal DOF): ASCII 58 and
// binary 58b, real and complex ordinates, single and double precision, even
// and uneven abscissa. The exchange format of modal-testing tools.
//
// Layout and the decisions this project takes (digits written, what is
// skipped, how FRF names map to nodes): docs/formats.md, section "UFF58".
//
// Reference: SDRC/Siemens I-DEAS Universal File Format, dataset 58 and 58b.
#pragma once

#include <complex>
#include <string>
#include <vector>

namespace ambdiag {

struct FrfData;

struct UffAxis {
  // 0 unknown, 1 general, ..., 8 displacement, 11 velocity, 12 acceleration,
  // 13 excitation force, 17 time, 18 frequency, ...
  int spec_data_type = 0;
  int length_exp = 0;
  int force_exp = 0;
  int temp_exp = 0;
  std::string label;  // 20 characters at most; trailing blanks are not significant
  std::string units;  // 20 characters at most; bytes kept as they are (not re-encoded)
};

// One dataset 58 record. Field names follow the standard's records 1-11.
// Text fields are compared without leading/trailing blanks: the writer trims
// them and the reader returns them trimmed.
struct Uff58Record {
  std::string id1, id2, id3, id4, id5;  // records 1-5 (80 chars each)
  int func_type = 0;                    // 1 time response, 4 FRF, 9 PSD, ... (record 6, field 1)
  int func_id = 0;
  int version = 0;
  int load_case_id = 0;
  std::string rsp_ent_name = "NONE";  // 10 characters at most
  int rsp_node = 0;
  int rsp_dir = 0;  // 0 scalar, +-1..3 X/Y/Z, +-4..6 rotation about X/Y/Z
  std::string ref_ent_name = "NONE";
  int ref_node = 0;
  int ref_dir = 0;
  int ord_data_type = 4;  // 2 real single, 4 real double, 5 complex single, 6 complex double
  bool even_spacing = true;
  double x_min = 0.0;  // record 7; when evenly spaced x[i] = x_min + i * dx
  double dx = 0.0;     // > 0 when evenly spaced with more than one point
  double z_axis_value = 0.0;
  UffAxis abscissa, ordinate_num, ordinate_den, z_axis;  // records 8-11
  // Abscissa, always filled on read (generated when evenly spaced); the
  // writer uses it only for uneven spacing (x_min and dx otherwise).
  std::vector<double> x;
  // Ordinate; imaginary part 0 for real data. Single-precision records are
  // rounded to float on read.
  std::vector<std::complex<double>> y;

  bool is_complex() const { return ord_data_type == 5 || ord_data_type == 6; }
  bool is_double() const { return ord_data_type == 4 || ord_data_type == 6; }
};

// Reads every dataset 58/58b in a universal file (other datasets skipped).
// Throws InputError naming the file, the dataset (1-based, counting every
// dataset of the file) and the line on malformed or truncated input.
std::vector<Uff58Record> read_uff58(const std::string& path);
std::vector<Uff58Record> parse_uff58(const std::string& bytes, const std::string& source = "<bytes>");
// Writes records as ASCII 58 (binary == false) or binary 58b (little-endian
// IEEE); atomic. Lossless: read(write(r)) == r exactly for double records
// and to float precision for single ones. ASCII uses the standard field
// widths (E13.5, E20.12) when they hold every value exactly and wider ones
// (E16.8 single, E25.16 double) otherwise. Throws InputError for a record
// the format cannot hold (field too long or too large, non-finite value,
// imaginary part on a real record, sizes that disagree).
void write_uff58(const std::string& path, const std::vector<Uff58Record>& records, bool binary);
std::string format_uff58(const std::vector<Uff58Record>& records, bool binary);

// FRF matrix <-> dataset 58 records (one record per entry, func_type 4,
// complex double). Sensor and actuator names are kept in id4
// ("ambdiag: <output> / <input>") and mapped to nodes/directions, so
// frf_from_uff58(frf_to_uff58(f)) gives back names, quantity, unit,
// frequencies and values bit for bit; pump_id, run_id and speed_rpm travel
// in id2, id3 and id5. sigma and coh are not exported. Foreign FRF records
// are named from entity name, node and direction (`n12+X`, `ent:n3-Z`); a
// 0 Hz line is dropped (the FRF matrix starts above 0 Hz). Throws InputError
// on records that are not FRFs or do not share one abscissa.
std::vector<Uff58Record> frf_to_uff58(const FrfData& frf);
FrfData frf_from_uff58(const std::vector<Uff58Record>& records);

}  // namespace ambdiag
