// Typed errors of the toolkit. Every message names the file, the field and the value
// that is wrong; the command-line front end prints it as one line and exits non-zero.
#pragma once

#include <stdexcept>
#include <string>

namespace eco {

/// Base of every error the toolkit throws on purpose.
class Error : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// A file could not be opened, read, parsed or written.
class IoError : public Error {
public:
    using Error::Error;
};

/// A value (from a file, a flag or an API call) is missing or out of range.
class ValidationError : public Error {
public:
    using Error::Error;
};

}  // namespace eco
