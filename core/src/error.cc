#include "ambdiag/core/error.h"

namespace ambdiag {

void rethrow_with_context(const InputError& e, const std::string& context) {
  throw InputError(context + ": " + e.what());
}

}  // namespace ambdiag
