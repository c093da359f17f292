// The schema is consistent with itself, docs/scene.md is its rendering, and
// the example scene it documents loads.
#include <gtest/gtest.h>
#include <toml++/toml.h>

#include <set>
#include <string>

#include "libsabo/io/traffic.hpp"
#include "libsabo/scene/loader.hpp"
#include "libsabo/scene/schema.hpp"
#include "scene_test_support.hpp"

namespace sabo::scene {
namespace {

bool matches_type(const toml::node& node, schema::Type type) {
  using schema::Type;
  const auto* array = node.as_array();
  switch (type) {
    case Type::boolean: return node.is_boolean();
    case Type::integer: return node.is_integer();
    case Type::number: return node.is_number();
    case Type::string: return node.is_string();
    case Type::vec3: return array != nullptr && array->size() == 3 && array->is_homogeneous(toml::node_type::none);
    case Type::number_pair: return array != nullptr && array->size() == 2;
    case Type::string_list:
      return array != nullptr && (array->empty() || array->is_homogeneous(toml::node_type::string));
    default: return false;  // tables have no literal defaults
  }
}

TEST(SceneSchema, DefaultsParseAndLieInTheirOwnRange) {
  std::size_t checked = 0;
  for (const schema::Table* table : schema::tables()) {
    for (const schema::Key& key : table->keys) {
      SCOPED_TRACE(table->title + " " + key.name);
      EXPECT_FALSE(key.description.empty());
      const bool is_table = key.type == schema::Type::table || key.type == schema::Type::table_list ||
                            key.type == schema::Type::named_tables;
      EXPECT_EQ(is_table, key.table != nullptr);
      if (key.required) {
        EXPECT_FALSE(key.example.empty()) << "a required key needs an example for the fix";
        EXPECT_TRUE(key.default_value.empty());
      }
      if (key.default_value.empty()) continue;
      const toml::table parsed = toml::parse("value = " + key.default_value);
      const toml::node& value = *parsed.get("value");
      EXPECT_TRUE(matches_type(value, key.type)) << key.default_value;
      if (const auto number = value.value<double>(); number && value.is_number()) {
        EXPECT_TRUE(key.range.contains(*number)) << key.default_value << " outside " << key.range.text();
      }
      if (const auto text = value.value<std::string>(); text && !key.choices.empty()) {
        EXPECT_NE(std::find(key.choices.begin(), key.choices.end(), *text), key.choices.end());
      }
      ++checked;
    }
  }
  std::cout << "keys with defaults checked: " << checked << "\n";
  EXPECT_GT(checked, 30u);
}

TEST(SceneSchema, AnchorsAreUniqueAndEveryTableIsReachable) {
  std::set<std::string> anchors;
  std::set<const schema::Table*> reachable{&schema::root()};
  for (const schema::Table* table : schema::tables()) {
    EXPECT_TRUE(anchors.insert(table->anchor).second) << table->anchor;
    for (const auto& key : table->keys) {
      if (key.table != nullptr) reachable.insert(key.table);
    }
  }
  for (const schema::Table* table : schema::tables()) {
    if (!table->keys.empty()) {
      EXPECT_TRUE(reachable.count(table) == 1) << table->title;
    }
  }
}

TEST(SceneSchema, RangeText) {
  schema::Range range;
  range.min = 0;
  range.min_exclusive = true;
  EXPECT_EQ(range.text(), "> 0");
  EXPECT_FALSE(range.contains(0.0));
  EXPECT_TRUE(range.contains(1e-300));
  range.max = 1;
  EXPECT_EQ(range.text(), "(0, 1]");
  EXPECT_TRUE(range.contains(1.0));
  range.max_exclusive = true;
  EXPECT_FALSE(range.contains(1.0));
  range.min_exclusive = false;
  EXPECT_EQ(range.text(), "[0, 1)");
  EXPECT_TRUE(range.contains(0.0));
}

TEST(SceneSchema, DocsAreTheGeneratedReference) {
  const auto docs = testing::source_dir() / "docs/scene.md";
  EXPECT_EQ(testing::read_text(docs), schema::markdown())
      << "docs/scene.md is stale: regenerate it with `sabo_scene schema-doc > docs/scene.md`";
  const auto result = testing::run_tool("schema-doc");
  EXPECT_EQ(result.exit_code, 0) << result.err;
  EXPECT_EQ(result.out, schema::markdown());
}

TEST(SceneSchema, DocsNameEveryKey) {
  const std::string docs = schema::markdown();
  for (const schema::Table* table : schema::tables()) {
    for (const auto& key : table->keys) EXPECT_NE(docs.find("| `" + key.name + "` |"), std::string::npos) << key.name;
  }
}

TEST(SceneSchema, ExampleSceneLoads) {
  testing::TempFolder folder;
  const auto file = folder.write("example.toml", std::string(schema::example_scene()));
  const Scene scene = load_scene(file);
  EXPECT_EQ(scene.particle_sets.size(), 2u);
  EXPECT_EQ(scene.structures.size(), 1u);
  EXPECT_DOUBLE_EQ(scene.surface_contact("marker", "chute").friction, 0.4);
  EXPECT_DOUBLE_EQ(scene.surface_contact("boulders", "chute").friction, 0.3);
  EXPECT_EQ(scene.recording.every, 10u);
}

}  // namespace
}  // namespace sabo::scene

// The recorder owns the field names; the schema's choices must name the same set.
TEST(SceneSchema, RecordingFieldsAreTheRecordersFields) {
  const sabo::scene::schema::Table* recording = nullptr;
  for (const auto* table : sabo::scene::schema::tables()) {
    if (table->anchor == "recording") recording = table;
  }
  ASSERT_NE(recording, nullptr);
  const auto* fields = recording->find("fields");
  ASSERT_NE(fields, nullptr);
  const std::set<std::string> in_schema(fields->choices.begin(), fields->choices.end());
  const auto& names = sabo::io::traffic_field_names();
  const std::set<std::string> in_recorder(names.begin(), names.end());
  for (const auto& name : in_recorder)
    EXPECT_TRUE(in_schema.count(name)) << "recorder field missing in schema: " << name;
  for (const auto& name : in_schema)
    EXPECT_TRUE(in_recorder.count(name)) << "schema field unknown to recorder: " << name;
}
