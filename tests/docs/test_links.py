"""Every relative link of the repository's Markdown files resolves inside the repository (issue 21): the
file it names exists, and an anchor it names (`file.md#anchor`) is a heading or an `<a id>` of that file.
Links to the web (http, https, mailto) are not followed."""
import os
import re
import subprocess
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
CODE = re.compile(r"```.*?```|`[^`\n]*`", re.S)


def markdown_files():
    listed = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard", "*.md"], cwd=ROOT,
                            capture_output=True, text=True, check=True).stdout.split()
    return sorted(path for path in listed if os.path.isfile(os.path.join(ROOT, path)))


def anchors(path):
    """GitHub's anchors of a Markdown file: its headings' slugs and explicit <a id> / <a name>."""
    with open(path, encoding="utf-8") as handle:
        text = handle.read()
    found = set(re.findall(r"<a\s+(?:id|name)=\"([^\"]+)\"", text))
    counts = {}
    for heading in re.findall(r"^#{1,6}\s+(.*?)\s*#*\s*$", CODE.sub(lambda m: m.group(0) if "\n" not in m.group(0)
                                                                     else "", text), re.M):
        slug = re.sub(r"[^\w\- ]", "", heading.lower()).replace(" ", "-")
        n = counts.get(slug, 0)
        counts[slug] = n + 1
        found.add(slug if n == 0 else "{}-{}".format(slug, n))
    return found


class RelativeLinksTest(unittest.TestCase):
    def test_every_relative_link_resolves_inside_the_repository(self):
        broken, checked = [], 0
        for relative in markdown_files():
            path = os.path.join(ROOT, relative)
            with open(path, encoding="utf-8") as handle:
                lines = CODE.sub(lambda m: "\n" * m.group(0).count("\n"), handle.read()).split("\n")
            for number, line in enumerate(lines, 1):
                for target in LINK.findall(line):
                    if re.match(r"[a-z][a-z0-9+.-]*:", target):
                        continue  # http:, https:, mailto:
                    checked += 1
                    file_part, _, anchor = target.partition("#")
                    resolved = os.path.normpath(os.path.join(os.path.dirname(path), file_part)) if file_part else path
                    where = "{}:{}: ({})".format(relative, number, target)
                    if os.path.relpath(resolved, ROOT).startswith(".."):
                        broken.append(where + " points outside the repository")
                    elif not os.path.exists(resolved):
                        broken.append(where + " names a file that does not exist")
                    elif anchor and resolved.endswith(".md") and anchor not in anchors(resolved):
                        broken.append(where + " names an anchor that {} does not have".format(
                            os.path.relpath(resolved, ROOT)))
        print("{} relative links checked in {} Markdown files, {} broken".format(
            checked, len(markdown_files()), len(broken)))
        self.assertEqual(broken, [], "\n".join(broken))


if __name__ == "__main__":
    unittest.main()
