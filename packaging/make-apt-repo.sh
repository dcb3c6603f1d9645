#!/usr/bin/env bash
# Turns a directory of .debs (amd64, arm64 or both) into a signed flat APT repository that robots use with one
# sources.list line:
#   packaging/make-apt-repo.sh DEBS_DIR REPO_DIR
# REPO_DIR gets the packages, Packages(.gz), Release, InRelease and Release.gpg, and rcand-archive-keyring.gpg (the
# public key, binary, for `signed-by`). Serve REPO_DIR over HTTP (or copy it to the robot), install the keyring as
# /usr/share/keyrings/rcand-archive-keyring.gpg, then:
#   deb [signed-by=/usr/share/keyrings/rcand-archive-keyring.gpg] http://fleet.example/rcand ./
# Signing key: the secret key in the GnuPG home RCAND_REPO_GNUPGHOME (default REPO_DIR/../<name>.gnupg, made with a
# new ed25519 key on first use; keep it, or every robot needs the new keyring). RCAND_REPO_KEY picks a key by id.
# Running it again with more .debs adds them (several versions of a package may sit side by side).
# Needs dpkg-dev (dpkg-scanpackages), apt-utils (apt-ftparchive) and gpg.
set -euo pipefail
debs=$(realpath "${1:?usage: make-apt-repo.sh DEBS_DIR REPO_DIR}")
mkdir -p "${2:?usage: make-apt-repo.sh DEBS_DIR REPO_DIR}"
repo=$(realpath "$2")
for tool in dpkg-scanpackages apt-ftparchive gpg; do
  command -v "$tool" > /dev/null || { echo "make-apt-repo: $tool is missing (dpkg-dev, apt-utils, gpg)" >&2; exit 1; }
done

export GNUPGHOME=${RCAND_REPO_GNUPGHOME:-$(dirname "$repo")/$(basename "$repo").gnupg}
if [ ! -d "$GNUPGHOME" ]; then
  mkdir -m 0700 -p "$GNUPGHOME"
  gpg --batch --quiet --passphrase '' --quick-generate-key "rcand packages (local repository) <packages@rcand.invalid>" \
    ed25519 sign never
  echo "make-apt-repo: new signing key in $GNUPGHOME (keep it: robots trust its public key)"
fi
key=${RCAND_REPO_KEY:-$(gpg --batch --list-secret-keys --with-colons | awk -F: '$1 == "fpr" { print $10; exit }')}
[ -n "$key" ] || { echo "make-apt-repo: no secret key in $GNUPGHOME" >&2; exit 1; }

cp -f "$debs"/*.deb "$repo"/
cd "$repo"
dpkg-scanpackages --multiversion . /dev/null > Packages 2> /dev/null
gzip -9nkf Packages
apt-ftparchive -o APT::FTPArchive::Release::Origin=rcand -o APT::FTPArchive::Release::Label=rcand \
  -o APT::FTPArchive::Release::Suite=stable release . > Release
rm -f InRelease Release.gpg
gpg --batch --yes --local-user "$key" --clearsign --output InRelease Release
gpg --batch --yes --local-user "$key" --armor --detach-sign --output Release.gpg Release
gpg --batch --yes --export "$key" > rcand-archive-keyring.gpg
echo "make-apt-repo: $(grep -c '^Package:' Packages) package(s) in $repo, signed by $key"
