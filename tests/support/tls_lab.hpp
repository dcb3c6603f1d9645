// A throwaway PKI for TLS tests and benchmarks, made at run time with the openssl command into a private temporary
// directory (removed with it): a test CA, a server certificate for 127.0.0.1/localhost, the same server's
// certificate already expired, a server certificate from another CA, and a client certificate for mutual TLS.
// Keys are P-256, mode 600.
#pragma once

#include <sys/stat.h>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "rcand_process.hpp"
#include "temp_dir.hpp"

namespace rcand::test {

class TlsLab {
 public:
  TlsLab() {
    make_ca("ca", "rcand test CA");
    make_ca("other-ca", "some other CA");
    make_leaf("server", "ca", "localhost", "subjectAltName=IP:127.0.0.1,DNS:localhost\nextendedKeyUsage=serverAuth\n", 2);
    // The same key, certified until yesterday.
    sign("expired", "server", "ca", "subjectAltName=IP:127.0.0.1,DNS:localhost\nextendedKeyUsage=serverAuth\n", -1);
    make_leaf("other", "other-ca", "localhost", "subjectAltName=IP:127.0.0.1,DNS:localhost\nextendedKeyUsage=serverAuth\n", 2);
    make_leaf("client", "ca", "operator", "extendedKeyUsage=clientAuth\n", 2);
  }

  // <name>.pem (certificate) and <name>.key: ca, other-ca, server, expired (key: server.key), other, client.
  std::filesystem::path pem(const std::string& name) const { return dir_.path() / (name + ".pem"); }
  std::filesystem::path key(const std::string& name) const {
    return dir_.path() / ((name == "expired" ? "server" : name) + ".key");
  }
  const std::filesystem::path& dir() const noexcept { return dir_.path(); }

  // runtime.listen.tls for a server certificate `name` (and mutual TLS against `client_ca`).
  nlohmann::json listen_tls(const std::string& name, const std::string& client_ca = {}) const {
    nlohmann::json tls{{"cert_file", pem(name).string()}, {"key_file", key(name).string()}};
    if (!client_ca.empty()) tls["client_ca_file"] = pem(client_ca).string();
    return tls;
  }

 private:
  void openssl(const std::vector<std::string>& args) const {
    const auto result = run_tool("/usr/bin/openssl", args);
    if (result.exit_code != 0) throw std::runtime_error("openssl " + args.front() + " failed: " + result.err);
  }
  std::string at(const std::string& file) const { return (dir_.path() / file).string(); }

  void make_ca(const std::string& name, const std::string& common_name) {
    openssl({"req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes", "-keyout", at(name + ".key"),
             "-out", at(name + ".pem"), "-days", "2", "-subj", "/CN=" + common_name, "-addext",
             "basicConstraints=critical,CA:TRUE", "-addext", "keyUsage=critical,keyCertSign,cRLSign"});
    ::chmod(at(name + ".key").c_str(), 0600);
  }
  void make_leaf(const std::string& name, const std::string& ca, const std::string& common_name, const std::string& extensions,
                 int days) {
    openssl({"req", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes", "-keyout", at(name + ".key"), "-out",
             at(name + ".csr"), "-subj", "/CN=" + common_name});
    ::chmod(at(name + ".key").c_str(), 0600);
    sign(name, name, ca, extensions, days);
  }
  // Certifies <csr_of>.csr as <name>.pem, signed by `ca`, valid for `days` from now (negative: already expired).
  void sign(const std::string& name, const std::string& csr_of, const std::string& ca, const std::string& extensions, int days) {
    dir_.write(name + ".ext", extensions);
    openssl({"x509", "-req", "-in", at(csr_of + ".csr"), "-CA", at(ca + ".pem"), "-CAkey", at(ca + ".key"), "-CAcreateserial",
             "-out", at(name + ".pem"), "-days", std::to_string(days), "-extfile", at(name + ".ext")});
  }

  TempDir dir_{"rcand-tls"};
};

}  // namespace rcand::test
