#!/usr/bin/env bash
# Builds the Unity package's C# with Mono's compiler, outside the editor, and runs its tests:
#   the engine-free core (Pinchmatch.Core.dll, no UnityEngine reference: it must build without one),
#   the components and the sample against the stubs of exactly the UnityEngine and XR Hands
#   members they use,
#   the console entry (pinchmatch-unity.exe) and the core's NUnit tests (nunit-console).
# usage: unity/build.sh [OUT_DIR]   (default: unity/build~); needs Debian's mono-mcs, mono-runtime and
# nunit-console (.ci/run installs them). Exits non-zero when a build or a test fails.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
pkg="$here/com.pinchmatch.unity"
out="${1:-$here/build~}"
mkdir -p "$out"
nunit_dll="$(ls /usr/lib/cli/nunit.framework-*/nunit.framework.dll | head -n 1)"
mcs="mcs -langversion:7.2 -nologo -warnaserror+ -debug-"

$mcs -target:library -out:"$out/Pinchmatch.Core.dll" "$pkg"/Runtime/Core/*.cs
$mcs -target:library -out:"$out/UnityEngine.Stubs.dll" "$pkg"/Tests/EngineStubs~/*.cs
$mcs -target:library -out:"$out/Pinchmatch.Unity.dll" -r:"$out/Pinchmatch.Core.dll" \
    -r:"$out/UnityEngine.Stubs.dll" "$pkg"/Runtime/Components/*.cs
$mcs -target:library -out:"$out/Pinchmatch.Unity.Samples.dll" -r:"$out/Pinchmatch.Core.dll" \
    -r:"$out/Pinchmatch.Unity.dll" -r:"$out/UnityEngine.Stubs.dll" "$pkg"/Samples~/*/*.cs
$mcs -target:exe -out:"$out/pinchmatch-unity.exe" -r:"$out/Pinchmatch.Core.dll" "$pkg"/Tools~/Console/*.cs
$mcs -target:library -out:"$out/Pinchmatch.Core.Tests.dll" -r:"$out/Pinchmatch.Core.dll" \
    -r:"$nunit_dll" "$pkg"/Tests/Core/*.cs
cp "$nunit_dll" "$out/"
cd "$out"
nunit-console -nologo -noshadow -xml="$out/TestResult.xml" Pinchmatch.Core.Tests.dll
