#pragma once
// Typed exceptions for user and input errors. Internal invariants use assert.
// Library code throws; only main() functions turn errors into exit codes.
#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>

namespace sabo {

// Text read from an input file as an error message may quote it: at most `max_bytes` of it ("..." after a
// cut), and every byte that is not printable ASCII (a NUL, a control character, a byte of binary data)
// written as \xNN, so that the message is one line that no NUL cuts short (what() is a C string).
inline std::string excerpt(std::string_view text, std::size_t max_bytes = 60) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out;
  for (std::size_t k = 0; k < text.size() && k < max_bytes; ++k) {
    const auto c = static_cast<unsigned char>(text[k]);
    if (c >= 0x20 && c < 0x7F) {
      out += static_cast<char>(c);
    } else {
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 0xF];
    }
  }
  if (text.size() > max_bytes) out += "...";
  return out;
}

// Base of every error a user can cause (bad scene, bad file, bad command line).
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A scene file is wrong. what() is the full, user-facing message:
// "FILE:LINE: key 'a.b' = VALUE: problem. Fix: ..."
class SceneError : public Error {
 public:
  using Error::Error;
};

// An input file (mesh, checkpoint, recording) cannot be read or is malformed.
class FileError : public Error {
 public:
  using Error::Error;
};

// A peer sent something that breaks the protocol.
class ProtocolError : public Error {
 public:
  using Error::Error;
};

// A physics model (DemModel, SphModel, FemModel) was handed input that does not fit it: forces for an entity it
// does not have, arrays of the wrong length, values that are not finite. The process around the model
// reports it as its failure; the model itself knows nothing of where the input came from.
class ModelInputError : public Error {
 public:
  using Error::Error;
};

// A library call (ZeroMQ, HDF5) failed; what() carries the library's own text.
class LibraryError : public Error {
 public:
  using Error::Error;
};

// An endpoint cannot be bound or connected because of what it names: a host that is not an address of this
// machine, a port in use, a socket folder that does not exist. what() names the endpoint, what is wrong and
// the fix.
class EndpointError : public Error {
 public:
  using Error::Error;
};

// The run was stopped on purpose (Ctrl-C, Stop message).
class StopRequested : public Error {
 public:
  using Error::Error;
};

}  // namespace sabo
