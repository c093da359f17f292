#pragma once
// Typed exceptions for user and input errors. Internal invariants use assert.
// Library code throws; only main() functions turn errors into exit codes.
#include <stdexcept>
#include <string>

namespace sabo {

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

// A library call (ZeroMQ, HDF5) failed; what() carries the library's own text.
class LibraryError : public Error {
 public:
  using Error::Error;
};

// The run was stopped on purpose (Ctrl-C, Stop message).
class StopRequested : public Error {
 public:
  using Error::Error;
};

}  // namespace sabo
