#include "explain_screen.h"

#include <algorithm>
#include <cmath>
#include <set>

#include <Eigen/LU>

namespace ambdiag::detail {

namespace {

using cd = std::complex<double>;

// The node matrices of the lateral system without structural damping and
// reduction: their differences are a candidate's change.
struct Bare {
  Eigen::SparseMatrix<double> k, m, c;
};

Bare bare(const PlantModel& p, double rpm) {
  PlantModel q = p;
  q.structural_damping = {};
  q.reduction = {};
  RotorSystem s = assemble_rotor(q, rpm);
  return {std::move(s.k), std::move(s.m), std::move(s.c)};
}

std::vector<int> entry_dofs(const PlantModel& p, const FrfData& meas, bool sensors) {
  std::vector<int> out;
  for (const auto& e : meas.entries) {
    const MeasurementPoint* s = p.find_sensor(e.output);
    const MeasurementPoint* a = p.find_actuator(e.input);
    const bool lateral = s && a && !s->is_axial() && !a->is_axial() && s->node && a->node;
    out.push_back(!lateral ? -1 : sensors ? lateral_dof(*s->node, s->dir) : lateral_dof(*a->node, a->dir));
  }
  return out;
}

void collect(const Eigen::SparseMatrix<double>& d, double tol, std::set<int>& dofs) {
  for (int k = 0; k < d.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(d, k); it; ++it)
      if (std::abs(it.value()) > tol) {
        dofs.insert(static_cast<int>(it.row()));
        dofs.insert(static_cast<int>(it.col()));
      }
}

Eigen::MatrixXd restrict(const Eigen::SparseMatrix<double>& d, const std::vector<int>& dofs) {
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(dofs.size()), static_cast<Eigen::Index>(dofs.size()));
  for (size_t r = 0; r < dofs.size(); ++r)
    for (size_t c = 0; c < dofs.size(); ++c) out(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = d.coeff(dofs[r], dofs[c]);
  return out;
}

double max_abs(const Eigen::SparseMatrix<double>& a) {
  double m = 0.0;
  for (int k = 0; k < a.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(a, k); it; ++it) m = std::max(m, std::abs(it.value()));
  return m;
}

}  // namespace

RotorScreen::RotorScreen(const PlantVariant& current, PlantFrfEvaluator& eval) : current_(current), eval_(eval) {
  const FrfData& meas = eval.measured();
  for (double f : meas.freq_hz) omega_.push_back(2.0 * M_PI * f);
  StructuralDampingOptions damping;
  damping.omega_max_rad_per_s = omega_.back();
  const RotorSystem sys = assemble_rotor(current.plant, eval.speed_rpm(current.plant), damping);
  g_ = std::make_unique<RotorReceptance>(sys, omega_);
  base_sensor_dof_ = entry_dofs(current.plant, meas, true);
  base_actuator_dof_ = entry_dofs(current.plant, meas, false);
  std::vector<int> rows, cols;
  for (size_t e = 0; e < base_sensor_dof_.size(); ++e) {
    for (int d : {base_sensor_dof_[e]})
      if (d >= 0 && std::find(rows.begin(), rows.end(), d) == rows.end()) rows.push_back(d);
    for (int d : {base_actuator_dof_[e]})
      if (d >= 0 && std::find(cols.begin(), cols.end(), d) == cols.end()) cols.push_back(d);
  }
  for (size_t e = 0; e < base_sensor_dof_.size(); ++e) {
    if (base_sensor_dof_[e] < 0 || base_actuator_dof_[e] < 0) {
      base_index_.push_back(-1);
      continue;
    }
    const auto r = std::find(rows.begin(), rows.end(), base_sensor_dof_[e]) - rows.begin();
    const auto c = std::find(cols.begin(), cols.end(), base_actuator_dof_[e]) - cols.begin();
    base_index_.push_back(static_cast<int>(r * static_cast<long>(cols.size()) + c));
  }
  base_ = g_->block(rows, cols).transpose();  // entries x lines: one line's entries contiguous
  sensor_dofs_ = rows;
  actuator_dofs_ = cols;
  std::vector<int> all(static_cast<size_t>(sys.full_dof_count));
  for (size_t d = 0; d < all.size(); ++d) all[d] = static_cast<int>(d);
  col_a_ = g_->block(all, cols);
  row_s_ = g_->block(rows, all);
}

Eigen::MatrixXcd RotorScreen::block(const std::vector<int>& rows, const std::vector<int>& cols) const {
  const Eigen::Index lines = static_cast<Eigen::Index>(omega_.size());
  const auto nr = static_cast<Eigen::Index>(rows.size()), nc = static_cast<Eigen::Index>(cols.size());
  auto pos = [](const std::vector<int>& v, int d) {
    const auto it = std::find(v.begin(), v.end(), d);
    return it == v.end() ? -1 : static_cast<int>(it - v.begin());
  };
  const auto n_all = static_cast<Eigen::Index>(col_a_.cols() / std::max<Eigen::Index>(1, static_cast<Eigen::Index>(actuator_dofs_.size())));
  Eigen::MatrixXcd out(lines, nr * nc);
  bool cols_are_actuators = true, rows_are_sensors = true;
  for (int c : cols) cols_are_actuators &= pos(actuator_dofs_, c) >= 0;
  for (int r : rows) rows_are_sensors &= pos(sensor_dofs_, r) >= 0;
  const auto na = static_cast<Eigen::Index>(actuator_dofs_.size());
  if (cols_are_actuators) {  // G[any, a]
    for (Eigen::Index r = 0; r < nr; ++r)
      for (Eigen::Index c = 0; c < nc; ++c) out.col(r * nc + c) = col_a_.col(rows[static_cast<size_t>(r)] * na + pos(actuator_dofs_, cols[static_cast<size_t>(c)]));
    return out;
  }
  if (rows_are_sensors) {  // G[s, any]
    for (Eigen::Index r = 0; r < nr; ++r)
      for (Eigen::Index c = 0; c < nc; ++c) out.col(r * nc + c) = row_s_.col(pos(sensor_dofs_, rows[static_cast<size_t>(r)]) * n_all + cols[static_cast<size_t>(c)]);
    return out;
  }
  if (rows == cols) {
    auto it = uu_.find(rows);
    if (it == uu_.end()) it = uu_.emplace(rows, g_->block(rows, cols)).first;
    return it->second;
  }
  return g_->block(rows, cols);
}

std::optional<LowRankChange> RotorScreen::change_of(const Candidate& c) const {
  if (c.node_impedance) return impedance_change(c);
  const double rpm = eval_.speed_rpm(current_.plant);
  const Bare b0 = bare(current_.plant, rpm);
  std::vector<double> x0;
  for (const auto& p : c.params) x0.push_back(p.initial);
  std::vector<Bare> steps;
  PlantVariant v0 = current_;
  c.apply(x0, v0);
  steps.push_back(bare(v0.plant, rpm));
  for (size_t i = 0; i < c.params.size(); ++i) {
    std::vector<double> x = x0;
    x[i] += c.params[i].scale;
    PlantVariant v = current_;
    c.apply(x, v);
    steps.push_back(bare(v.plant, rpm));
  }
  const double tk = 1e-12 * max_abs(b0.k), tm = 1e-12 * max_abs(b0.m), tc = 1e-12 * std::max(max_abs(b0.c), 1.0);
  std::set<int> dofs;
  std::vector<Bare> diffs;
  for (size_t i = 0; i < steps.size(); ++i) {
    const Bare& ref = i == 0 ? b0 : steps[0];
    Bare d{steps[i].k - ref.k, steps[i].m - ref.m, steps[i].c - ref.c};
    collect(d.k, tk, dofs);
    collect(d.m, tm, dofs);
    collect(d.c, tc, dofs);
    diffs.push_back(std::move(d));
  }
  const std::vector<int> sensors = entry_dofs(v0.plant, eval_.measured(), true);
  if ((dofs.empty() && sensors == base_sensor_dof_) || dofs.size() > 24) return std::nullopt;

  LowRankChange ch;
  ch.dofs.assign(dofs.begin(), dofs.end());
  for (const auto& d : diffs) {
    ch.dk.push_back(restrict(d.k, ch.dofs));
    ch.dm.push_back(restrict(d.m, ch.dofs));
    ch.dc.push_back(restrict(d.c, ch.dofs));
  }
  finish_change(ch, sensors);
  return ch;
}

// Distinct (moved) sensor and actuator DOFs of the lateral entries, and the
// receptance blocks the Woodbury update needs.
void RotorScreen::finish_change(LowRankChange& ch, const std::vector<int>& sensors) const {
  std::vector<int> rows, cols;
  auto index_of = [](std::vector<int>& v, int dof) {
    auto it = std::find(v.begin(), v.end(), dof);
    if (it != v.end()) return static_cast<int>(it - v.begin());
    v.push_back(dof);
    return static_cast<int>(v.size()) - 1;
  };
  for (size_t e = 0; e < sensors.size(); ++e) {
    const bool lateral = sensors[e] >= 0 && base_actuator_dof_[e] >= 0;
    ch.sensor_row.push_back(lateral ? index_of(rows, sensors[e]) : -1);
    ch.actuator_col.push_back(lateral ? index_of(cols, base_actuator_dof_[e]) : -1);
  }
  ch.n_rows = static_cast<int>(rows.size());
  ch.n_cols = static_cast<int>(cols.size());
  // Stored transposed (entries x lines): one line's entries are contiguous.
  ch.g_sa = block(rows, cols).transpose();
  if (!ch.dofs.empty()) {
    ch.g_su = block(rows, ch.dofs).transpose();
    ch.g_uu = block(ch.dofs, ch.dofs).transpose();
    ch.g_ua = block(ch.dofs, cols).transpose();
  }
}

// A node impedance: U is the node's x and y, no node-matrix change, the
// sensors where they are; the impedance enters per line in residual_change.
std::optional<LowRankChange> RotorScreen::impedance_change(const Candidate& c) const {
  LowRankChange ch;
  ch.dofs = {lateral_dof(c.impedance_node, 'x'), lateral_dof(c.impedance_node, 'y')};
  for (size_t i = 0; i <= c.params.size(); ++i) {
    ch.dk.push_back(Eigen::MatrixXd::Zero(2, 2));
    ch.dm.push_back(Eigen::MatrixXd::Zero(2, 2));
    ch.dc.push_back(Eigen::MatrixXd::Zero(2, 2));
  }
  finish_change(ch, base_sensor_dof_);
  return ch;
}

std::vector<cd> RotorScreen::residual_change(const LowRankChange& ch, const Candidate& c, const std::vector<double>& x,
                                             const std::vector<int>& lines) const {
  const FrfData& meas = eval_.measured();
  const size_t ne = meas.entries.size();
  const auto nu = static_cast<Eigen::Index>(ch.dofs.size());
  const Eigen::Index nr = ch.n_rows, nc = ch.n_cols;
  // dZ(w) = K' - w^2 M' + j w C' with the parameter steps summed once.
  Eigen::MatrixXd k = ch.dk[0], m = ch.dm[0], cm = ch.dc[0];
  for (size_t i = 0; i < c.params.size(); ++i) {
    const double u = (x[i] - c.params[i].initial) / c.params[i].scale;
    if (u == 0.0) continue;
    k += u * ch.dk[i + 1];
    m += u * ch.dm[i + 1];
    cm += u * ch.dc[i + 1];
  }
  std::vector<cd> out(ne * lines.size(), cd(0.0, 0.0));
  const auto nuu = static_cast<size_t>(nu);
  std::vector<cd> dz(nuu * nuu), a(nuu * nuu), t(nuu * nuu), tg(nuu * static_cast<size_t>(nc));
  Eigen::MatrixXcd hsa(nr, nc);
  for (size_t q = 0; q < lines.size(); ++q) {
    const auto l = static_cast<Eigen::Index>(lines[q]);
    const double w = omega_[static_cast<size_t>(l)];
    const cd* gsa = &ch.g_sa(0, l);
    for (Eigen::Index r = 0; r < nr; ++r)
      for (Eigen::Index j = 0; j < nc; ++j) hsa(r, j) = gsa[r * nc + j];
    if (nu > 0) {
      const cd* guu = &ch.g_uu(0, l);
      const cd* gsu = &ch.g_su(0, l);
      const cd* gua = &ch.g_ua(0, l);
      for (size_t r = 0; r < nuu; ++r)
        for (size_t j = 0; j < nuu; ++j) {
          const auto rr = static_cast<Eigen::Index>(r), jj = static_cast<Eigen::Index>(j);
          dz[r * nuu + j] = cd(k(rr, jj) - w * w * m(rr, jj), w * cm(rr, jj));
        }
      if (c.node_impedance) {
        const cd z = c.node_impedance(w, x);
        for (size_t r = 0; r < nuu; ++r) dz[r * nuu + r] += z;
      }
      // a = I + dZ G_uu; solve a t = dZ by Gaussian elimination with
      // partial pivoting (|U| is a few DOFs).
      for (size_t r = 0; r < nuu; ++r)
        for (size_t j = 0; j < nuu; ++j) {
          cd sum = r == j ? cd(1.0, 0.0) : cd(0.0, 0.0);
          for (size_t p = 0; p < nuu; ++p) sum += dz[r * nuu + p] * guu[p * nuu + j];
          a[r * nuu + j] = sum;
        }
      t = dz;
      for (size_t col = 0; col < nuu; ++col) {
        size_t piv = col;
        for (size_t r = col + 1; r < nuu; ++r)
          if (std::norm(a[r * nuu + col]) > std::norm(a[piv * nuu + col])) piv = r;
        if (piv != col)
          for (size_t j = 0; j < nuu; ++j) {
            std::swap(a[col * nuu + j], a[piv * nuu + j]);
            std::swap(t[col * nuu + j], t[piv * nuu + j]);
          }
        const cd d = a[col * nuu + col];
        const cd inv = std::conj(d) / std::norm(d);
        for (size_t r = col + 1; r < nuu; ++r) {
          const cd f = a[r * nuu + col] * inv;
          if (f == cd(0.0, 0.0)) continue;
          for (size_t j = col; j < nuu; ++j) a[r * nuu + j] -= f * a[col * nuu + j];
          for (size_t j = 0; j < nuu; ++j) t[r * nuu + j] -= f * t[col * nuu + j];
        }
      }
      for (size_t col = nuu; col-- > 0;) {
        const cd d = a[col * nuu + col];
        const cd inv = std::conj(d) / std::norm(d);
        for (size_t j = 0; j < nuu; ++j) {
          cd sum = t[col * nuu + j];
          for (size_t p = col + 1; p < nuu; ++p) sum -= a[col * nuu + p] * t[p * nuu + j];
          t[col * nuu + j] = sum * inv;
        }
      }
      const auto ncc = static_cast<size_t>(nc);
      for (size_t r = 0; r < nuu; ++r)
        for (size_t j = 0; j < ncc; ++j) {
          cd sum(0.0, 0.0);
          for (size_t p = 0; p < nuu; ++p) sum += t[r * nuu + p] * gua[p * ncc + j];
          tg[r * ncc + j] = sum;
        }
      for (Eigen::Index r = 0; r < nr; ++r)
        for (size_t j = 0; j < ncc; ++j) {
          cd sum(0.0, 0.0);
          for (size_t p = 0; p < nuu; ++p) sum += gsu[static_cast<size_t>(r) * nuu + p] * tg[p * ncc + j];
          hsa(r, static_cast<Eigen::Index>(j)) -= sum;
        }
    }
    const cd phase = std::polar(1.0, -w * current_.delay_s);
    for (size_t e = 0; e < ne; ++e) {
      if (ch.sensor_row[e] < 0 || base_index_[e] < 0) continue;
      // Against the current rotor with the sensor where it was.
      const cd before = base_(base_index_[e], l);
      const cd after = hsa(ch.sensor_row[e], ch.actuator_col[e]);
      out[e * lines.size() + q] = (after - before) * phase / eval_.sigma(e, static_cast<size_t>(l));
    }
  }
  return out;
}

std::vector<cd> RotorScreen::residual_with(const LowRankChange& ch, const Candidate& c, const std::vector<double>& x,
                                           const std::vector<int>& lines, const std::vector<cd>& base) const {
  std::vector<cd> d = residual_change(ch, c, x, lines);
  for (size_t k = 0; k < d.size(); ++k) d[k] += base[k];
  return d;
}

}  // namespace ambdiag::detail
