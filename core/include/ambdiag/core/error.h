// Error types shared by every ambdiag library.
//
// Three kinds of failure, three mechanisms (docs/architecture.md):
//  - a broken invariant is a bug: assert;
//  - bad input (a file, message, request or option) throws InputError with a
//    message that names what is wrong (`shaft[3].od: must be > id`); it is
//    caught at the boundary (CLI exit 3, HTTP 400, a rejected DDS sample);
//  - an expected outcome (no fault found, did not converge) is a value.
#pragma once

#include <stdexcept>
#include <string>

namespace ambdiag {

// Bad input. `what()` names the file or source, then the field, line or
// column, then what is wrong.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Prefixes an InputError's message with a context such as a file name;
// used where a reader knows where the text came from.
[[noreturn]] void rethrow_with_context(const InputError& e, const std::string& context);

}  // namespace ambdiag
