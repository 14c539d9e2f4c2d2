using System;
using System.Collections.Generic;
using NUnit.Framework;
using Pinchmatch;

namespace Pinchmatch.Tests
{
    [TestFixture]
    public class JsonTests
    {
        [Test]
        public void ReadsNestedValuesOfEveryKind()
        {
            var d = (Dictionary<string, object>)Json.Parse(
                " {\"a\": [1, -2.5, true, false, null], \"b\": {\"c\": \"x\"}, \"e\": []}\n");
            var a = (List<object>)d["a"];
            Assert.AreEqual(1.0, a[0]);
            Assert.AreEqual(-2.5, a[1]);
            Assert.AreEqual(true, a[2]);
            Assert.AreEqual(false, a[3]);
            Assert.IsNull(a[4]);
            Assert.AreEqual("x", ((Dictionary<string, object>)d["b"])["c"]);
            Assert.AreEqual(0, ((List<object>)d["e"]).Count);
        }

        [TestCase("1e3", 1000.0)]
        [TestCase("-0.25E-2", -0.0025)]
        [TestCase("0", 0.0)]
        [TestCase("123456789.123456789", 123456789.123456789)]
        public void ReadsNumbersAsDoubles(string text, double expected)
        {
            Assert.AreEqual(expected, (double)Json.Parse(text));
        }

        [Test]
        public void ReadsEscapes()
        {
            Assert.AreEqual("a\"b\\c/\n\t\u00e9", Json.Parse("\"a\\\"b\\\\c\\/\\n\\t\\u00e9\""));
        }

        [TestCase("{\"a\": 1} x", "after")]
        [TestCase("{\"a\": 1", "unclosed")]
        [TestCase("\"abc", "unclosed")]
        [TestCase("[1, 2,]", "unexpected")]
        [TestCase("01", "after")]
        [TestCase("-", "digits")]
        [TestCase("1.", "digits")]
        [TestCase("tru", "true")]
        [TestCase("{1: 2}", "key")]
        [TestCase("", "end")]
        public void RefusesWhatIsNotJson(string text, string word)
        {
            var e = Assert.Throws<JsonException>(() => Json.Parse(text));
            StringAssert.Contains(word, e.Message);
        }

        [Test]
        public void RefusesNestingDeeperThanItsLimit()
        {
            Assert.Throws<JsonException>(() => Json.Parse(new string('[', 600) + new string(']', 600)));
            Assert.DoesNotThrow(() => Json.Parse(new string('[', 100) + new string(']', 100)));
        }

        [Test]
        public void WritesWhatItReadsBack()
        {
            var value = Fixtures.Obj("x", 0.1 + 0.2, "s", "q\"\n\u0001", "l", Fixtures.L(1.0, null, true));
            var back = (Dictionary<string, object>)Json.Parse(Json.Write(value));
            Assert.AreEqual(0.1 + 0.2, back["x"]);
            Assert.AreEqual("q\"\n\u0001", back["s"]);
            Assert.AreEqual(3, ((List<object>)back["l"]).Count);
        }

        [Test]
        public void WritesNonFiniteNumbersAsNull()
        {
            Assert.AreEqual("[null,null]", Json.Write(Fixtures.L(double.NaN, double.PositiveInfinity)));
        }
    }
}
