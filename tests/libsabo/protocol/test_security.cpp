// The run's key set (libsabo/protocol/security.hpp): written private, read back, and every way a key file can be
// wrong refused with the file, the line and the fix.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "libsabo/core/error.hpp"
#include "libsabo/protocol/security.hpp"

namespace sabo::protocol {
namespace {

namespace fs = std::filesystem;

const std::vector<std::string> kNames{"coupler", "dem_solver", "fem_solver"};

class KeySetTest : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() / ("sabo-keys-" + std::to_string(::getpid()) + "-" +
                                           ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(folder_);
    write_key_set(folder_, kNames, false);
  }
  void TearDown() override { fs::remove_all(folder_); }

  static unsigned mode_of(const fs::path& path) {
    struct stat info {};
    EXPECT_EQ(::stat(path.c_str(), &info), 0) << path;
    return info.st_mode & 07777;
  }
  std::string error_of(const std::function<void()>& action) const {
    try {
      action();
    } catch (const FileError& error) {
      return error.what();
    }
    ADD_FAILURE() << "no FileError";
    return {};
  }

  fs::path folder_;
};

TEST_F(KeySetTest, IsWrittenPrivateWhateverTheUmaskAndReadsBack) {
  fs::remove_all(folder_);
  const mode_t before = ::umask(0);
  write_key_set(folder_, kNames, false);
  ::umask(before);
  EXPECT_EQ(mode_of(folder_), 0700u);
  for (const auto& entry : fs::directory_iterator(folder_)) EXPECT_EQ(mode_of(entry.path()), 0600u) << entry.path();
  EXPECT_EQ(std::distance(fs::directory_iterator(folder_), fs::directory_iterator{}), 7);

  const CurveKeys dem = read_certificate(secret_key_file(folder_, "dem_solver"), true);
  EXPECT_EQ(dem.public_key.size(), 40u);
  EXPECT_EQ(dem.secret_key.size(), 40u);
  EXPECT_EQ(read_certificate(public_key_file(folder_, "dem_solver"), false).public_key, dem.public_key);
  EXPECT_TRUE(read_certificate(public_key_file(folder_, "dem_solver"), false).secret_key.empty());
  ASSERT_TRUE(decode_key(dem.public_key));
  EXPECT_EQ(decode_key(dem.public_key)->size(), 32u);
  EXPECT_FALSE(decode_key("too short"));
  EXPECT_NE(dem.public_key, read_certificate(public_key_file(folder_, "fem_solver"), false).public_key);

  const std::vector<std::string> roles{"dem_solver", "fem_solver"};
  const ServerCredentials tcp = read_server_credentials(folder_, roles, "tcp://127.0.0.1:5555");
  EXPECT_EQ(tcp.mechanism, Mechanism::curve);
  ASSERT_EQ(tcp.clients.size(), 2u);
  EXPECT_EQ(tcp.clients.at(*decode_key(dem.public_key)), "dem_solver");
  const ServerCredentials ipc = read_server_credentials(folder_, roles, "ipc:///run/coupler.sock");
  EXPECT_EQ(ipc.mechanism, Mechanism::plain);
  EXPECT_EQ(ipc.token.size(), 64u);
  EXPECT_EQ(ipc.token, read_client_credentials(folder_, "dem_solver", "ipc:///run/coupler.sock").token);
  const ClientCredentials client = read_client_credentials(folder_, "dem_solver", "tcp://10.0.0.1:5555");
  EXPECT_EQ(client.mechanism, Mechanism::curve);
  EXPECT_EQ(client.own.public_key, dem.public_key);
  EXPECT_EQ(client.server_key, tcp.own.public_key);
}

TEST_F(KeySetTest, AKeySetIsNotReplacedUnlessAskedTo) {
  const auto before = read_token(folder_);
  const std::string message = error_of([&] { write_key_set(folder_, kNames, false); });
  std::cout << message << "\n";
  EXPECT_NE(message.find("a key set is already there"), std::string::npos);
  EXPECT_NE(message.find("--force"), std::string::npos);
  EXPECT_EQ(read_token(folder_), before);
  write_key_set(folder_, kNames, true);
  EXPECT_NE(read_token(folder_), before);
}

TEST_F(KeySetTest, BadKeyFilesAreRefusedNamingTheFileLineAndFix) {
  const fs::path secret = secret_key_file(folder_, "dem_solver");
  // Readable by others: refused as ssh refuses a private key.
  ::chmod(secret.c_str(), 0644);
  std::string message = error_of([&] { (void)read_certificate(secret, true); });
  std::cout << message << "\n";
  EXPECT_NE(message.find(secret.string() + ": others may read this secret (mode 0644)"), std::string::npos);
  EXPECT_NE(message.find("chmod 600"), std::string::npos);
  ::chmod(secret.c_str(), 0600);

  // A key that is not Z85.
  std::ifstream in(secret);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto at = text.find("secret-key = \"") + 14;
  std::string broken = text;
  broken.replace(at, 40, "not a key");
  std::ofstream(secret) << broken;
  message = error_of([&] { (void)read_certificate(secret, true); });
  std::cout << message << "\n";
  EXPECT_NE(message.find(secret.string() + ":8: secret-key is not a CURVE key"), std::string::npos);
  EXPECT_NE(message.find("./sabo keys " + folder_.string()), std::string::npos);

  // The public key of another pair.
  std::string swapped = text;
  const CurveKeys other = make_curve_keys();
  swapped.replace(text.find("public-key = \"") + 14, 40, other.public_key);
  std::ofstream(secret) << swapped;
  message = error_of([&] { (void)read_certificate(secret, true); });
  EXPECT_NE(message.find("its public-key is not the one of its secret-key"), std::string::npos) << message;

  // A public certificate where the secret one belongs, a missing file, a bad token.
  fs::copy_file(public_key_file(folder_, "dem_solver"), secret, fs::copy_options::overwrite_existing);
  ::chmod(secret.c_str(), 0600);
  message = error_of([&] { (void)read_certificate(secret, true); });
  EXPECT_NE(message.find("no secret-key in it"), std::string::npos) << message;
  message = error_of([&] { (void)read_client_credentials(folder_, "sph_solver", "tcp://127.0.0.1:1"); });
  EXPECT_NE(message.find("sph_solver.key_secret: cannot open the key file"), std::string::npos) << message;
  std::ofstream(folder_ / kTokenFile) << "0123\n";
  message = error_of([&] { (void)read_token(folder_); });
  EXPECT_NE(message.find("ipc.token:1: not a token (64 hexadecimal digits expected, got '0123')"), std::string::npos)
      << message;
}

}  // namespace
}  // namespace sabo::protocol
