#include "libsabo/protocol/security.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zmq.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <fstream>

#include "libsabo/core/error.hpp"

namespace sabo::protocol {

namespace fs = std::filesystem;

namespace {

constexpr std::size_t kZ85KeyLength = 40;
constexpr std::size_t kTokenBytes = 32;

std::string new_key_set_fix(const fs::path& folder) {
  return fmt::format("write a new key set with './sabo keys {}' (it replaces the files with --force)", folder.string());
}

// Writes `text` to `file` with mode 0600 whatever the umask: a temporary file, then a rename.
void write_private_file(const fs::path& file, const std::string& text) {
  const fs::path temporary = file.string() + ".tmp";
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) {
    throw FileError(fmt::format("{}: cannot create it: {}. Fix: write the key set into a folder you own",
                                temporary.string(), std::strerror(errno)));
  }
  bool ok = ::fchmod(fd, 0600) == 0;
  std::size_t written = 0;
  while (ok && written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n < 0 && errno == EINTR) continue;
    ok = n > 0;
    if (ok) written += static_cast<std::size_t>(n);
  }
  ok = ::fsync(fd) == 0 && ok;
  const int saved = errno;
  ok = ::close(fd) == 0 && ok;
  if (!ok || ::rename(temporary.c_str(), file.c_str()) != 0) {
    const std::string why = std::strerror(ok ? errno : saved);
    ::unlink(temporary.c_str());
    throw FileError(fmt::format("{}: cannot write it: {}", file.string(), why));
  }
}

std::string certificate_text(const CurveKeys& keys, bool with_secret) {
  std::array<char, 32> date{};
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  std::strftime(date.data(), date.size(), "%Y-%m-%d %H:%M:%S UTC", &utc);
  std::string text = fmt::format("#   ****  Generated on {} by Sabo  ****\n", date.data());
  if (with_secret) {
    text +=
        "#   ZeroMQ CURVE **Secret** Certificate\n"
        "#   DO NOT PROVIDE THIS FILE TO OTHER USERS nor change its permissions.\n\n";
  } else {
    text +=
        "#   ZeroMQ CURVE Public Certificate\n"
        "#   Exchange securely, or use a secure mechanism to verify the contents\n"
        "#   of this file after exchange.\n\n";
  }
  text += "metadata\ncurve\n";
  text += fmt::format("    public-key = \"{}\"\n", keys.public_key);
  if (with_secret) text += fmt::format("    secret-key = \"{}\"\n", keys.secret_key);
  return text;
}

// Refuses a secret file that another user may read or change (as ssh does with its keys).
void check_private(const fs::path& file, const fs::path& folder) {
  struct stat info {};
  if (::stat(file.c_str(), &info) != 0) return;  // the open reports it
  if ((info.st_mode & 077) != 0) {
    throw FileError(fmt::format("{}: others may read this secret (mode {:04o}). Fix: chmod 600 {}, or {}",
                                file.string(), info.st_mode & 07777, file.string(), new_key_set_fix(folder)));
  }
  if (info.st_uid != ::geteuid()) {
    throw FileError(fmt::format("{}: belongs to user {}, not to this user ({}). Fix: {}", file.string(), info.st_uid,
                                ::geteuid(), new_key_set_fix(folder)));
  }
}

std::string random_token() {
  std::array<unsigned char, kTokenBytes> bytes{};
  std::size_t filled = 0;
  while (filled < bytes.size()) {
    const ssize_t n = ::getrandom(bytes.data() + filled, bytes.size() - filled, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw LibraryError(fmt::format("getrandom: {}", std::strerror(errno)));
    filled += static_cast<std::size_t>(n);
  }
  std::string hex;
  for (const unsigned char b : bytes) hex += fmt::format("{:02x}", b);
  return hex;
}

}  // namespace

CurveKeys make_curve_keys() {
  std::array<char, kZ85KeyLength + 1> public_key{};
  std::array<char, kZ85KeyLength + 1> secret_key{};
  if (zmq_curve_keypair(public_key.data(), secret_key.data()) != 0) {
    throw LibraryError(
        fmt::format("ZeroMQ: cannot make a CURVE key pair: {} (errno {}); this libzmq was built without CURVE "
                    "(Debian's libzmq5 has it)",
                    zmq_strerror(zmq_errno()), zmq_errno()));
  }
  return {public_key.data(), secret_key.data()};
}

std::optional<std::string> decode_key(const std::string& z85) {
  if (z85.size() != kZ85KeyLength) return std::nullopt;
  std::array<std::uint8_t, 32> bytes{};
  if (zmq_z85_decode(bytes.data(), z85.c_str()) == nullptr) return std::nullopt;
  return std::string(reinterpret_cast<const char*>(bytes.data()), bytes.size());
}

Transport transport_of(const std::string& endpoint) {
  if (endpoint.starts_with("ipc://")) return Transport::ipc;
  if (endpoint.starts_with("tcp://")) return Transport::tcp;
  return Transport::other;
}

const char* mechanism_name(Mechanism mechanism) {
  switch (mechanism) {
    case Mechanism::none: return "none";
    case Mechanism::plain: return "token";
    case Mechanism::curve: return "curve";
  }
  return "unknown";
}

fs::path public_key_file(const fs::path& folder, const std::string& name) {
  return folder / (name + ".key");
}
fs::path secret_key_file(const fs::path& folder, const std::string& name) {
  return folder / (name + ".key_secret");
}

void write_key_set(const fs::path& folder, std::span<const std::string> names, bool replace) {
  std::error_code error;
  if (!fs::exists(folder, error)) {
    if (::mkdir(folder.c_str(), 0700) != 0) {
      throw FileError(fmt::format("{}: cannot create the folder: {}", folder.string(), std::strerror(errno)));
    }
  } else if (!fs::is_directory(folder, error)) {
    throw FileError(fmt::format("{}: is not a folder. Fix: name a folder for the key set", folder.string()));
  }
  if (::chmod(folder.c_str(), 0700) != 0) {
    throw FileError(fmt::format("{}: cannot make it private (chmod 700): {}", folder.string(), std::strerror(errno)));
  }
  std::vector<fs::path> files{folder / kTokenFile};
  for (const auto& name : names) {
    files.push_back(public_key_file(folder, name));
    files.push_back(secret_key_file(folder, name));
  }
  if (!replace) {
    for (const auto& file : files) {
      if (fs::exists(file, error)) {
        throw FileError(fmt::format(
            "{}: a key set is already there. Fix: use it as it is, name another folder, or replace it with --force "
            "(processes that hold the old keys can then no longer join)",
            file.string()));
      }
    }
  }
  for (const auto& name : names) {
    const CurveKeys keys = make_curve_keys();
    write_private_file(public_key_file(folder, name), certificate_text(keys, false));
    write_private_file(secret_key_file(folder, name), certificate_text(keys, true));
  }
  write_private_file(folder / kTokenFile, random_token() + "\n");
}

CurveKeys read_certificate(const fs::path& file, bool with_secret) {
  const fs::path folder = file.parent_path();
  std::ifstream in(file);
  if (!in) {
    throw FileError(fmt::format("{}: cannot open the key file: {}. Fix: {}", file.string(), std::strerror(errno),
                                new_key_set_fix(folder)));
  }
  if (with_secret) check_private(file, folder);
  CurveKeys keys;
  std::string line;
  int number = 0;
  auto value_of = [&](const std::string& key) -> std::optional<std::string> {
    const auto start = line.find_first_not_of(" \t");
    if (start == std::string::npos || line.compare(start, key.size(), key) != 0) return std::nullopt;
    const auto open = line.find('"', start + key.size());
    const auto close = open == std::string::npos ? open : line.find('"', open + 1);
    if (close == std::string::npos || line.find_first_not_of(" \t=", start + key.size()) != open) {
      throw FileError(fmt::format("{}:{}: '{}': expected {} = \"40 Z85 characters\". Fix: {}", file.string(), number,
                                  excerpt(line), key, new_key_set_fix(folder)));
    }
    std::string value = line.substr(open + 1, close - open - 1);
    if (!decode_key(value)) {
      throw FileError(fmt::format("{}:{}: {} is not a CURVE key (40 Z85 characters, got {}: '{}'). Fix: {}",
                                  file.string(), number, key, value.size(), excerpt(value), new_key_set_fix(folder)));
    }
    return value;
  };
  while (std::getline(in, line)) {
    ++number;
    if (auto v = value_of("public-key")) keys.public_key = *v;
    if (auto v = value_of("secret-key")) keys.secret_key = *v;
  }
  if (keys.public_key.empty()) {
    throw FileError(fmt::format("{}: no public-key in it: not a ZeroMQ certificate. Fix: {}", file.string(),
                                new_key_set_fix(folder)));
  }
  if (with_secret) {
    if (keys.secret_key.empty()) {
      throw FileError(
          fmt::format("{}: no secret-key in it (a public certificate where the secret one belongs). Fix: {}",
                      file.string(), new_key_set_fix(folder)));
    }
    std::array<char, kZ85KeyLength + 1> derived{};
    if (zmq_curve_public(derived.data(), keys.secret_key.c_str()) != 0 || keys.public_key != derived.data()) {
      throw FileError(fmt::format("{}: its public-key is not the one of its secret-key. Fix: {}", file.string(),
                                  new_key_set_fix(folder)));
    }
  } else {
    keys.secret_key.clear();
  }
  return keys;
}

std::string read_token(const fs::path& folder) {
  const fs::path file = folder / kTokenFile;
  std::ifstream in(file);
  if (!in) {
    throw FileError(fmt::format("{}: cannot open the run's token: {}. Fix: {}", file.string(), std::strerror(errno),
                                new_key_set_fix(folder)));
  }
  check_private(file, folder);
  std::string token;
  std::getline(in, token);
  if (token.size() != 2 * kTokenBytes || token.find_first_not_of("0123456789abcdef") != std::string::npos) {
    throw FileError(fmt::format("{}:1: not a token ({} hexadecimal digits expected, got '{}'). Fix: {}", file.string(),
                                2 * kTokenBytes, excerpt(token), new_key_set_fix(folder)));
  }
  return token;
}

ClientCredentials read_client_credentials(const fs::path& folder, const std::string& name,
                                          const std::string& endpoint) {
  ClientCredentials credentials;
  switch (transport_of(endpoint)) {
    case Transport::tcp:
      credentials.mechanism = Mechanism::curve;
      credentials.own = read_certificate(secret_key_file(folder, name), true);
      credentials.server_key = read_certificate(public_key_file(folder, kCouplerKeyName), false).public_key;
      break;
    case Transport::ipc:
      credentials.mechanism = Mechanism::plain;
      credentials.user = name;
      credentials.token = read_token(folder);
      break;
    case Transport::other: break;
  }
  return credentials;
}

ServerCredentials read_server_credentials(const fs::path& folder, std::span<const std::string> roles,
                                          const std::string& endpoint) {
  ServerCredentials credentials;
  credentials.roles.assign(roles.begin(), roles.end());
  switch (transport_of(endpoint)) {
    case Transport::tcp:
      credentials.mechanism = Mechanism::curve;
      credentials.own = read_certificate(secret_key_file(folder, kCouplerKeyName), true);
      for (const auto& role : roles) {
        const auto key = read_certificate(public_key_file(folder, role), false).public_key;
        credentials.clients[*decode_key(key)] = role;
      }
      break;
    case Transport::ipc:
      credentials.mechanism = Mechanism::plain;
      credentials.token = read_token(folder);
      break;
    case Transport::other: break;
  }
  return credentials;
}

}  // namespace sabo::protocol
