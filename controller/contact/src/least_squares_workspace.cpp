#include "poise/contact/least_squares_workspace.hpp"

#include <stdexcept>
#include <string>

namespace poise::contact::detail {

void LeastSquaresWorkspace::resize(const char* solver, int rows, int cols_max) {
  if (rows <= 0 || cols_max <= 0) {
    throw std::invalid_argument(std::string(solver) + "::resize: sizes must be positive, got " +
                                std::to_string(rows) + " x " + std::to_string(cols_max));
  }
  max_rows = rows;
  max_cols = cols_max;
  W.setZero(rows, cols_max);
  r.setZero(rows);
  qr_rhs.setZero(rows);
  diag.setZero(cols_max);
  w.setZero(cols_max);
  z.setZero(cols_max);
  cols.setZero(cols_max);
  state.setZero(cols_max);
  rejected.setZero(cols_max);
  AtA.setZero(cols_max, cols_max);
  Atb.setZero(cols_max);
  L.setZero(cols_max, cols_max);
  pivot.setZero(cols_max);
  rhs.setZero(cols_max);
  xb.setZero(cols_max);
}

}  // namespace poise::contact::detail
