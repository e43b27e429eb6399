// Universal File Format dataset 58 (function at nodal DOF): ASCII 58 and
// binary 58b, real and complex ordinates, single and double precision, even
// and uneven abscissa. The exchange format of modal-testing tools.
//
// Reference: SDRC/Siemens I-DEAS Universal File Format, dataset 58 and 58b.
#pragma once

#include <complex>
#include <string>
#include <vector>

namespace ambdiag {

struct FrfData;

struct UffAxis {
  int spec_data_type = 0;   // 0 unknown, 1 general, ..., 12 acceleration, 13 excitation force, 17 time, 18 frequency, ...
  int length_exp = 0;
  int force_exp = 0;
  int temp_exp = 0;
  std::string label;
  std::string units;
};

// One dataset 58 record. Field names follow the standard's records 1-11.
struct Uff58Record {
  std::string id1, id2, id3, id4, id5;  // records 1-5 (80 chars each)
  int func_type = 0;        // 1 time response, 4 FRF, 9 PSD, ... (record 6, field 1)
  int func_id = 0;
  int version = 0;
  int load_case_id = 0;
  std::string rsp_ent_name = "NONE";
  int rsp_node = 0;
  int rsp_dir = 0;
  std::string ref_ent_name = "NONE";
  int ref_node = 0;
  int ref_dir = 0;
  int ord_data_type = 4;    // 2 real single, 4 real double, 5 complex single, 6 complex double
  bool even_spacing = true;
  double x_min = 0.0;
  double dx = 0.0;
  double z_axis_value = 0.0;
  UffAxis abscissa, ordinate_num, ordinate_den, z_axis;  // records 8-11
  std::vector<double> x;  // abscissa, always filled (generated when evenly spaced)
  std::vector<std::complex<double>> y;  // ordinate; imaginary part 0 for real data

  bool is_complex() const { return ord_data_type == 5 || ord_data_type == 6; }
  bool is_double() const { return ord_data_type == 4 || ord_data_type == 6; }
};

// Reads every dataset 58/58b in a universal file (other datasets skipped).
// Throws InputError naming the file, dataset and line on malformed or
// truncated input.
std::vector<Uff58Record> read_uff58(const std::string& path);
std::vector<Uff58Record> parse_uff58(const std::string& bytes, const std::string& source = "<bytes>");
// Writes records as ASCII 58 (binary == false) or binary 58b; atomic.
void write_uff58(const std::string& path, const std::vector<Uff58Record>& records, bool binary);
std::string format_uff58(const std::vector<Uff58Record>& records, bool binary);

// FRF matrix <-> dataset 58 records (one record per entry, func_type 4).
// Sensor and actuator names are kept in id lines and mapped to node/dir.
std::vector<Uff58Record> frf_to_uff58(const FrfData& frf);
FrfData frf_from_uff58(const std::vector<Uff58Record>& records);

}  // namespace ambdiag
